"""Pack a `weft simgen` dataset into a few compact files, to carry it to a training machine.

  /usr/bin/python3 tools/train/pack.py --data data/refsim --out data/pack --max-mb 40
  /usr/bin/python3 tools/train/train.py --data data/pack ...     # train.py reads packs directly
  /usr/bin/python3 tools/train/pack.py --data data/refsim --out data/pack --append   # after the set grew

With --append, sequences already packed under --out (in any part) are left as they are and the new
ones go into new parts after the last, so parts already carried to a training machine stay valid.
--split S packs one split only; --max-frames N keeps each sequence's first N frames; --interleave
spreads each --data root's sequences evenly over the packing order, so every part mixes them (e.g.
real-motion windows and procedural garments) in proportion.

One `NAME.wpk.npz` per accepted sequence, grouped into folders `part0/`, `part1/`, ... of at most
--max-mb each (so each part fits one transfer). The coding is lossy in a controlled way:
  - positions are snapped to a grid (--cloth-step, default 20 µm; --collider-step, default 50 µm)
    and stored as second differences in time (smooth motion gives small integers), byte-shuffled
    and deflated; decoding is exact integer arithmetic, so the error is at most half a step;
  - collider triangles that can never enter the model's crop (the garment's box at t grown by the
    model's crop_margin, tested against the triangle at t+1, as model.crop_mask) in any frame are
    dropped, with the vertices only they use. The model sees exactly the same kept tokens.
  - with --skin DIR, the S track of the "skinned" prior (DIR/<name>.npy from `weft eval --method
    lbs --write-pos DIR`, see data.py) is stored like the cloth track; a sequence without one is
    an error (a skinned-prior model cannot train on it).
  - the pin mask (pinned.npy, [T, V] u8) is stored bit-packed and deflated (exact).
meta.json travels inside each file, with the split from the dataset's manifest written into it.
"""
import argparse
import glob
import json
import os
import sys
import zlib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import data as weft_data  # noqa: E402

FORMAT = "weft-pack-1"


def encode_track(x, step):
    """[T, V, 3] float -> dict of arrays: grid ints, second differences in time, byte-shuffled."""
    q = np.round(np.asarray(x, dtype=np.float64) / step).astype(np.int64)
    d = q.copy()
    d[1:] = q[1:] - q[:-1]
    d2 = d.copy()
    d2[2:] = d[2:] - d[1:-1]
    head = d2[:2].astype(np.int64)
    tail = d2[2:]
    width = 2 if tail.size == 0 or np.abs(tail).max() < 32767 else 4
    raw = tail.astype("<i2" if width == 2 else "<i4").tobytes()
    shuffled = np.frombuffer(raw, np.uint8).reshape(-1, width).T.copy().tobytes()
    return {"head": head, "body": np.frombuffer(zlib.compress(shuffled, 9), np.uint8),
            "shape": np.array(q.shape, np.int64), "width": np.array(width, np.int64),
            "step": np.array(step, np.float64)}


def decode_track(z, prefix):
    shape = tuple(int(v) for v in z[prefix + "shape"])
    width = int(z[prefix + "width"])
    step = float(z[prefix + "step"])
    raw = zlib.decompress(z[prefix + "body"].tobytes())
    planes = np.frombuffer(raw, np.uint8).reshape(width, -1).T.copy()
    tail = np.frombuffer(planes.tobytes(), "<i2" if width == 2 else "<i4").astype(np.int64)
    d2 = np.concatenate([z[prefix + "head"].reshape(-1), tail]).reshape(shape)
    d = d2.copy()                                   # row 0 holds q[0], rows 1.. first differences
    d[1:] = np.cumsum(d2[1:], axis=0)
    q = np.cumsum(d, axis=0)
    return (q * step).astype(np.float32)


def crop_support(pos, cpos, cfaces, margin):
    """Indices of collider triangles that the model's crop keeps in at least one frame."""
    keep = np.zeros(len(cfaces), bool)
    for t in range(pos.shape[0] - 1):
        lo = pos[t].min(axis=0) - margin
        hi = pos[t].max(axis=0) + margin
        p = cpos[t + 1][cfaces]                      # (M, 3, 3)
        keep |= ((p.min(axis=1) <= hi) & (p.max(axis=1) >= lo)).all(axis=1)
    return np.nonzero(keep)[0]


def crop_collider(pos, cpos, cfaces, margin):
    """The collider cut to crop_support's triangles: (positions [T, used, 3], triangles renumbered
    onto them, number of triangles kept)."""
    tris = crop_support(pos, cpos, cfaces, margin)
    used = np.unique(cfaces[tris].reshape(-1))
    remap = -np.ones(cpos.shape[1], np.int64)
    remap[used] = np.arange(len(used))
    return np.ascontiguousarray(cpos[:, used]), remap[cfaces[tris]].astype(np.int32), len(tris)


def pack_sequence(seq, cloth_step, collider_step, margin, max_frames=0):
    """One sequence as the arrays of its .wpk.npz; with max_frames, only its first max_frames frames
    (cloth, S track, pins and collider alike)."""
    n = min(seq.frames, max_frames) if max_frames > 0 else seq.frames
    pos = np.asarray(seq.pos[:n], dtype=np.float32)
    meta = dict(seq.meta)
    meta["split"] = seq.split
    meta["pack"] = {"format": FORMAT, "cloth_step_m": cloth_step, "collider_step_m": collider_step,
                    "crop_margin_m": margin}
    if n < seq.frames:
        meta["pack"]["frames_kept"] = [int(n), int(seq.frames)]
    out = {"rest_pos": seq.rest.astype(np.float32), "faces": seq.faces.astype(np.int32)}
    for k, v in encode_track(pos, cloth_step).items():
        out["cloth_" + k] = v
    if seq.skin is not None:
        for k, v in encode_track(np.asarray(seq.skin[:n], dtype=np.float32), cloth_step).items():
            out["skin_" + k] = v
    pinned = None if seq.pinned is None else np.asarray(seq.pinned[:n])
    if pinned is not None and np.any(pinned):
        bits = np.packbits(pinned != 0, axis=None)
        out["pinned_bits"] = np.frombuffer(zlib.compress(bits.tobytes(), 9), np.uint8)
        out["pinned_shape"] = np.array(pinned.shape, np.int64)
    if seq.cpos is not None:
        kept_pos, out["collider_faces"], kept = crop_collider(pos, np.asarray(seq.cpos[:n], dtype=np.float32),
                                                             seq.cfaces, margin)
        meta["pack"]["collider_kept"] = [int(kept), int(len(seq.cfaces))]
        for k, v in encode_track(kept_pos, collider_step).items():
            out["collider_" + k] = v
    out["meta"] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    return out


class PackedSequence(weft_data.Sequence):
    """A sequence read from a .wpk.npz file (decoded into memory)."""

    def __init__(self, path):  # pylint: disable=super-init-not-called (fills the same fields)
        with np.load(path) as z:
            self.meta = json.loads(z["meta"].tobytes().decode())
            if self.meta.get("pack", {}).get("format") != FORMAT:
                raise ValueError(f"{path}: not a {FORMAT} file")
            self.pos = decode_track(z, "cloth_")
            self.rest = np.ascontiguousarray(z["rest_pos"], dtype=np.float32)
            self.faces = np.ascontiguousarray(z["faces"], dtype=np.int64)
            if "collider_faces" in z.files and len(z["collider_faces"]) > 0:
                self.cpos = decode_track(z, "collider_")
                self.cfaces = np.ascontiguousarray(z["collider_faces"], dtype=np.int64)
            else:
                self.cpos, self.cfaces = None, None
            self.skin = decode_track(z, "skin_") if "skin_body" in z.files else None
            self.pinned = None
            if "pinned_bits" in z.files:
                shape = tuple(int(v) for v in z["pinned_shape"])
                bits = np.frombuffer(zlib.decompress(z["pinned_bits"].tobytes()), np.uint8)
                self.pinned = np.unpackbits(bits, count=shape[0] * shape[1]).reshape(shape)
        self.folder = path
        self.name = os.path.basename(path)[:-len(".wpk.npz")]
        T, V = self.pos.shape[:2]
        bad_skin = self.skin is not None and self.skin.shape != self.pos.shape
        bad_pins = self.pinned is not None and self.pinned.shape != (T, V)
        if self.rest.shape != (V, 3) or self.faces.min() < 0 or self.faces.max() >= V or bad_skin or bad_pins:
            raise ValueError(f"{path}: arrays disagree")
        self.frames = T
        self.scenario = self.meta.get("scenario", "unknown")
        self.split = self.meta.get("split") or weft_data.default_split(self.name)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", nargs="+", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--max-mb", type=float, default=40.0, help="size of one part folder")
    ap.add_argument("--cloth-step", type=float, default=2e-5)
    ap.add_argument("--collider-step", type=float, default=5e-5)
    ap.add_argument("--crop-margin", type=float, default=0.15, help="the model's crop_margin (m)")
    ap.add_argument("--skin", default=None, help="folder of S tracks (<name>.npy) to store with each sequence")
    ap.add_argument("--check", action="store_true", help="decode each file and report the error")
    ap.add_argument("--skip-unskinned", action="store_true",
                    help="with --skin, leave out sequences that have no S track yet instead of failing")
    ap.add_argument("--append", action="store_true",
                    help="keep what is packed under --out; pack only new sequences, into new parts")
    ap.add_argument("--split", default=None, help="pack only this split's sequences (train, val, test)")
    ap.add_argument("--max-frames", type=int, default=0,
                    help="keep each sequence's first N frames only (e.g. validation windows scored on their start)")
    ap.add_argument("--interleave", action="store_true",
                    help="spread each --data root's sequences evenly over the packing order, so every part "
                         "holds the roots in proportion; default: root after root")
    a = ap.parse_args()
    skin = [a.skin] if a.skin else ()
    by_root = [[s for s in weft_data.load_sequences([r], a.split, skin_roots=skin)
                if s.meta.get("accepted", True)] for r in a.data]
    if a.interleave:  # each root's sequences spread evenly over the order (a smaller root less densely)
        order = sorted(((i + 0.5) / len(rs), r, i) for r, rs in enumerate(by_root) for i in range(len(rs)))
        seqs = [by_root[r][i] for _, r, i in order]
    else:
        seqs = [s for rs in by_root for s in rs]
    names = set()
    seqs = [s for s in seqs if not (s.name in names or names.add(s.name))]  # first root wins
    missing = [s.name for s in seqs if a.skin and s.skin is None]
    if missing and a.skip_unskinned:   # e.g. finished by a running simgen after the S track was written
        print(f"--skip-unskinned: {len(missing)} sequence(s) without an S track left out: {', '.join(missing[:5])}")
        seqs = [s for s in seqs if s.skin is not None]
        missing = []
    if missing:
        sys.exit(f"pack: no S track under {a.skin} for {len(missing)} sequence(s): {', '.join(missing[:5])}")
    os.makedirs(a.out, exist_ok=True)
    part, part_bytes, total = 0, 0, 0
    if a.append:
        packed = glob.glob(os.path.join(a.out, "part*", "*.wpk.npz"))
        done = {os.path.basename(p)[:-len(".wpk.npz")] for p in packed}
        parts = [int(os.path.basename(os.path.dirname(p))[4:]) for p in packed
                 if os.path.basename(os.path.dirname(p))[4:].isdigit()]
        part = max(parts) + 1 if parts else 0
        print(f"--append: {len(done)} sequence(s) already packed; new ones from part{part}")
        seqs = [s for s in seqs if s.name not in done]
    elif glob.glob(os.path.join(a.out, "part*", "*.wpk.npz")):
        sys.exit(f"pack: {a.out} already holds packed sequences: pass --append, or another --out")
    for i, s in enumerate(seqs):
        arrays = pack_sequence(s, a.cloth_step, a.collider_step, a.crop_margin, a.max_frames)
        folder = os.path.join(a.out, f"part{part}")
        os.makedirs(folder, exist_ok=True)
        path = os.path.join(folder, s.name + ".wpk.npz")
        np.savez(path, **arrays)
        size = os.path.getsize(path)
        if part_bytes > 0 and part_bytes + size > a.max_mb * 1e6:
            part += 1
            part_bytes = 0
            folder = os.path.join(a.out, f"part{part}")
            os.makedirs(folder, exist_ok=True)
            os.replace(path, os.path.join(folder, s.name + ".wpk.npz"))
            path = os.path.join(folder, s.name + ".wpk.npz")
        part_bytes += size
        total += size
        msg = f"[{i + 1}/{len(seqs)}] {s.name} {s.split} {size / 1e6:.2f} MB"
        if a.check:
            p = PackedSequence(path)
            e = np.abs(p.pos - np.asarray(s.pos[:p.frames])).max()
            msg += f" cloth err {e * 1e6:.1f} um"
            if p.skin is not None:
                msg += f", skin err {np.abs(p.skin - np.asarray(s.skin[:p.frames])).max() * 1e6:.1f} um"
            sp = None if s.pinned is None else np.asarray(s.pinned[:p.frames])
            if (p.pinned is None) != (sp is None or not np.any(sp)) or (
                    p.pinned is not None and not np.array_equal(p.pinned != 0, sp != 0)):
                sys.exit(f"pack: {s.name}: pin mask does not round-trip")
            if p.cpos is not None:
                msg += f", collider {p.cfaces.shape[0]}/{s.cfaces.shape[0]} tris"
        print(msg, flush=True)
    print(f"{len(seqs)} sequences, {total / 1e6:.1f} MB in {part + 1} part(s) under {a.out}")


if __name__ == "__main__":
    main()
