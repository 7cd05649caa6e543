"""Sequences in the `weft simgen` layout: one folder per sequence with meta.json and .npy arrays.

Array names accepted (the first present wins):
  cloth positions   cloth_pos.npy          [T, V, 3] float32
  rest shape        rest_pos.npy           [V, 3]
  cloth triangles   faces.npy / cloth_faces.npy   [F, 3] int
  collider          collider_pos.npy / obst_pos.npy / body_pos.npy   [T, Vc, 3] (optional)
  collider tris     collider_faces.npy / obst_faces.npy / body_faces.npy [Fc, 3] (optional)
  skinned garment   skin_pos.npy           [T, V, 3] (optional; the "skinned" prior's S track)
  pins              pinned.npy             [T, V] u8 (optional; 1 where a vertex follows the gripper
                                           or the waistband in that frame: train.py --pins)
A `topology.npz` with rest_pos / faces is read as well. Packed sequences (`*.wpk.npz`, written by
pack.py) are found below the roots too. meta.json may carry "scenario" and "split";
otherwise the split comes from the root's manifest.json / splits/*.txt (weft simgen), else from a
hash of the folder name (default_split, the rule weft simgen uses).

The S track is the skinning baseline's rollout, `weft eval --method lbs --ccd off --write-pos DIR`
(DIR/<name>.npy, the binding made on frame 1, so S_1 = X_1); load_sequences(..., skin_roots=[DIR])
attaches it, pack.py --skin DIR stores it. Frame 0 of that file is the reference frame, not S_0;
no prior reads S_0 (the first predicted frame is 2, whose prior uses S_2 - S_1).
"""
import glob
import json
import os

import numpy as np

_CLOTH = ["cloth_pos.npy"]
_REST = ["rest_pos.npy", "cloth_rest.npy"]
_FACES = ["faces.npy", "cloth_faces.npy"]
_CPOS = ["collider_pos.npy", "obst_pos.npy", "body_pos.npy"]
_CFACES = ["collider_faces.npy", "obst_faces.npy", "body_faces.npy"]


def _first(folder, names, required=True, mmap=True):
    for n in names:
        p = os.path.join(folder, n)
        if os.path.exists(p):
            return np.load(p, mmap_mode="r" if mmap else None)
    if required:
        raise FileNotFoundError(f"{folder}: none of {names}")
    return None


class Sequence:
    def __init__(self, folder):
        self.folder = folder
        self.name = os.path.basename(os.path.normpath(folder))
        with open(os.path.join(folder, "meta.json")) as f:
            self.meta = json.load(f)
        topo = None
        tp = os.path.join(folder, "topology.npz")
        if os.path.exists(tp):
            topo = np.load(tp)
        self.pos = _first(folder, _CLOTH)
        rest = _first(folder, _REST, required=topo is None, mmap=False)
        faces = _first(folder, _FACES, required=topo is None, mmap=False)
        if rest is None:
            rest = topo["rest_pos"]
        if faces is None:
            faces = topo["faces"]
        self.rest = np.ascontiguousarray(rest, dtype=np.float32)
        self.faces = np.ascontiguousarray(faces, dtype=np.int64)
        cpos = _first(folder, _CPOS, required=False)
        cfaces = _first(folder, _CFACES, required=False, mmap=False)
        if cpos is not None and cfaces is not None and len(cfaces) > 0:
            self.cpos = cpos
            self.cfaces = np.ascontiguousarray(cfaces, dtype=np.int64)
        else:
            self.cpos, self.cfaces = None, None
        T, V = self.pos.shape[:2]
        if self.pos.ndim != 3 or self.pos.shape[2] != 3 or self.rest.shape != (V, 3):
            raise ValueError(f"{folder}: cloth_pos {self.pos.shape} and rest {self.rest.shape} disagree")
        if self.faces.ndim != 2 or self.faces.shape[1] != 3 or self.faces.min() < 0 or self.faces.max() >= V:
            raise ValueError(f"{folder}: faces out of range")
        if self.cpos is not None:
            if self.cpos.shape[0] != T or self.cfaces.max() >= self.cpos.shape[1]:
                raise ValueError(f"{folder}: collider arrays disagree with the cloth")
        self.pinned = _first(folder, ["pinned.npy"], required=False)
        if self.pinned is not None and self.pinned.shape != (T, V):
            raise ValueError(f"{folder}: pinned {self.pinned.shape} does not match the cloth {self.pos.shape}")
        self.skin = None
        sp = os.path.join(folder, "skin_pos.npy")
        if os.path.exists(sp):
            self.attach_skin(np.load(sp, mmap_mode="r"), sp)
        self.frames = T
        self.scenario = self.meta.get("scenario", "unknown")
        self.split = self.meta.get("split") or default_split(self.name)

    def attach_skin(self, skin, where):
        """Set the S track ([T, V, 3], or longer: cut to the cloth's frames)."""
        T, V = self.pos.shape[:2]
        if skin.ndim != 3 or skin.shape[0] < T or skin.shape[1:] != (V, 3):
            raise ValueError(f"{where}: skin track {skin.shape} does not match the cloth {self.pos.shape}")
        self.skin = skin[:T]

    def skin_window(self, start, length):
        """Frames [start, start+length) of the S track as float32, or None without one."""
        return None if self.skin is None else np.array(self.skin[start:start + length], dtype=np.float32)

    def pin_window(self, start, length):
        """Frames [start, start+length) of the pin mask as bool [length, V], or None without pins."""
        if self.pinned is None:
            return None
        return np.array(self.pinned[start:start + length]) != 0

    def window(self, start, length):
        """Frames [start, start+length) as float32 arrays (cloth, collider or None)."""
        x = np.array(self.pos[start:start + length], dtype=np.float32)
        c = None if self.cpos is None else np.array(self.cpos[start:start + length], dtype=np.float32)
        return x, c


_M64 = (1 << 64) - 1


def _simgen_hash(name, seed0=0x5B11):
    """The name hash `weft simgen` splits by (FNV-1a then a splitmix64 finaliser)."""
    h = 1469598103934665603 ^ seed0
    for c in name.encode():
        h = ((h ^ c) * 1099511628211) & _M64
    h = ((h ^ (h >> 30)) * 0xBF58476D1CE4E5B9) & _M64
    h = ((h ^ (h >> 27)) * 0x94D049BB133111EB) & _M64
    return h ^ (h >> 31)


def default_split(name):
    """8:1:1 train/val/test by the same name hash as `weft simgen`, for sequences whose meta.json
    and manifest name no split (stable as the set grows)."""
    h = _simgen_hash(name) % 10
    return "train" if h < 8 else ("val" if h == 8 else "test")


def find_sequences(roots):
    """All sequence folders (those holding meta.json and cloth_pos.npy) below the given roots."""
    out = []
    for r in roots:
        for meta in sorted(glob.glob(os.path.join(r, "**", "meta.json"), recursive=True)):
            d = os.path.dirname(meta)
            if os.path.exists(os.path.join(d, "cloth_pos.npy")):
                out.append(d)
    return out


def manifest_splits(roots):
    """name -> split from `weft simgen`'s manifest.json (and splits/*.txt) under each root."""
    out = {}
    for r in roots:
        for sp in glob.glob(os.path.join(r, "splits", "*_*.txt")):
            split = os.path.basename(sp)[:-4].rsplit("_", 1)[1]
            with open(sp) as f:
                for line in f:
                    if line.strip():
                        out[line.strip()] = split
        mp = os.path.join(r, "manifest.json")
        if os.path.exists(mp):
            try:
                with open(mp) as f:
                    for e in json.load(f).get("sequences", []):
                        if "name" in e and "split" in e:
                            out[e["name"]] = e["split"]
            except (ValueError, OSError):
                pass
    return out


def find_packs(roots):
    """Packed sequences (tools/train/pack.py) below the given roots."""
    out = []
    for r in roots:
        out += sorted(glob.glob(os.path.join(r, "**", "*.wpk.npz"), recursive=True))
    return out


def load_sequences(roots, split=None, min_frames=8, skin_roots=()):
    """Sequences (folders and packs) below roots; with skin_roots, S tracks from <root>/<name>.npy
    are attached to sequences that do not carry one. A name found twice (a sequence generated
    beside a pack that already holds it) is loaded once: folders first, then packs, in root order."""
    seqs = []
    seen = {}
    named = manifest_splits(roots)
    packs = find_packs(roots)
    for d in find_sequences(roots) + packs:
        name = os.path.basename(d)[:-len(".wpk.npz")] if d.endswith(".wpk.npz") else os.path.basename(d)
        if name in seen:
            print(f"skipping {d}: {name} is already loaded from {seen[name]}")
            continue
        seen[name] = d
        try:
            if d.endswith(".wpk.npz"):
                from pack import PackedSequence  # noqa: E402 (pack imports this module)
                s = PackedSequence(d)
            else:
                s = Sequence(d)
        except (ValueError, FileNotFoundError, KeyError) as e:
            print(f"skipping {d}: {e}")
            continue
        if s.frames < min_frames:
            continue
        if "split" not in s.meta and s.name in named:
            s.split = named[s.name]
        if split is None or s.split == split:
            if s.skin is None:
                for r in skin_roots:
                    sp = os.path.join(r, s.name + ".npy")
                    if os.path.exists(sp):
                        s.attach_skin(np.load(sp, mmap_mode="r"), sp)
                        break
            seqs.append(s)
    return seqs
