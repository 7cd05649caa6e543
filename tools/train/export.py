"""Export a trained checkpoint to safetensors (F32, config in __metadata__) and, optionally,
golden tensors for the C parity test.

  /usr/bin/python3 tools/train/export.py --ckpt tools/train/runs/game/ckpt.pt \
      --out tools/train/models/game.safetensors --name game
  /usr/bin/python3 tools/train/export.py --ckpt data/runs/golden/ckpt.pt \
      --out tests/model/data/golden_model.safetensors --name golden \
      --golden tests/model/data --golden-seq tests/data/sample_seq

Golden files (.npy, little-endian float32/uint32): rest, faces, cfaces, gt_pos [T,V,3],
c_pos [T,Vc,3], tf_frames [n] (frame t of each teacher-forced step), tf_pred [n,V,3] (X_{t+1} from
GT X_t, X_{t-1}, C_t, C_{t+1} with an empty latent history) and rollout [R,V,3] (autoregressive
from GT frames 0 and 1; rollout[i] is frame i+2). With --golden-preds-only only the last three
are written: the test reads the others from the --golden-seq folder itself (its rest_pos, faces,
collider_faces, cloth_pos, collider_pos), as the skinned-prior test does:

  /usr/bin/python3 tools/train/export.py --ckpt data/runs/golden_skin/ckpt.pt \
      --out tests/model/data/garment_seq/golden_skin.safetensors --name golden_skin \
      --golden tests/model/data/garment_seq/golden --golden-seq tests/model/data/garment_seq \
      --tf-frames 1,2,5,10 --rollout 14 --golden-preds-only
"""
import argparse
import json
import os
import struct
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from data import Sequence  # noqa: E402
from model import ClothTransformer, export_tensors, mean_adjacency  # noqa: E402


def write_safetensors(path, tensors, metadata):
    """Minimal safetensors writer: sorted names, F32 only, header padded to 8 bytes."""
    header = {}
    offset = 0
    blobs = []
    for name in sorted(tensors):
        a = np.ascontiguousarray(tensors[name], dtype="<f4")
        b = a.tobytes()
        header[name] = {"dtype": "F32", "shape": list(a.shape), "data_offsets": [offset, offset + len(b)]}
        blobs.append(b)
        offset += len(b)
    header["__metadata__"] = {k: str(v) for k, v in metadata.items()}
    h = json.dumps(header, separators=(",", ":")).encode("utf-8")
    h += b" " * ((8 - len(h) % 8) % 8)
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(struct.pack("<Q", len(h)))
        f.write(h)
        for b in blobs:
            f.write(b)
    os.replace(tmp, path)


def read_safetensors(path):
    """Reader for round-trip checks: returns (tensors, metadata)."""
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        header = json.loads(f.read(n))
        data = f.read()
    meta = header.pop("__metadata__", {})
    out = {}
    for k, v in header.items():
        b, e = v["data_offsets"]
        out[k] = np.frombuffer(data[b:e], dtype="<f4").reshape(v["shape"])
    return out, meta


def load_model(ckpt_path):
    st = torch.load(ckpt_path, map_location="cpu")
    m = ClothTransformer(st["config"])
    m.load_state_dict(st["model"])
    m.eval()
    return m, st


def golden(model, seq, out_dir, tf_frames, rollout_len, seq_arrays=True):
    os.makedirs(out_dir, exist_ok=True)
    T = min(seq.frames, rollout_len + 2)
    x, c = seq.window(0, T)
    sk = seq.skin_window(0, T)
    if model.cfg["prior"] == "skinned" and sk is None:
        raise SystemExit(f"golden: the skinned prior needs the S track of {seq.folder} (skin_pos.npy)")
    sa = None if sk is None else torch.from_numpy(sk).unsqueeze(0)
    adj = mean_adjacency(seq.faces, seq.rest.shape[0])
    rest = torch.from_numpy(seq.rest).unsqueeze(0)
    ctri = None if seq.cfaces is None else torch.from_numpy(seq.cfaces)
    xa = torch.from_numpy(x).unsqueeze(0)
    ca = None if c is None else torch.from_numpy(c).unsqueeze(0)
    # pins (pinned.npy): the vertices pinned at t+1 take their reference positions, as `weft eval
    # --pins all` sets them (weft_garment_set_pins), and the grasp prior reads them
    pw = seq.pin_window(0, T)
    pa = None if pw is None else torch.from_numpy(pw).unsqueeze(0)

    def pinned(xn, t):
        return xn if pa is None else torch.where(pa[:, t + 1].unsqueeze(-1), xa[:, t + 1], xn)

    tf = []
    frames = [t for t in tf_frames if 1 <= t < T - 1]
    with torch.no_grad():
        for t in frames:
            cn = None if ca is None else ca[:, t + 1]
            cc = None if ca is None else ca[:, t]
            sn = None if sa is None else sa[:, t + 1]
            sc = None if sa is None else sa[:, t]
            pm = None if pa is None else pa[:, t + 1]
            xn, _ = model.step([], xa[:, t], xa[:, t - 1], rest, adj, cn, cc, ctri, sn, sc, pm, xa[:, t + 1])
            tf.append(pinned(xn, t)[0].numpy())
        hist, xp, xc, roll = [], xa[:, 0], xa[:, 1], []
        for t in range(1, T - 1):
            cn = None if ca is None else ca[:, t + 1]
            cc = None if ca is None else ca[:, t]
            sn = None if sa is None else sa[:, t + 1]
            sc = None if sa is None else sa[:, t]
            pm = None if pa is None else pa[:, t + 1]
            xn, hist = model.step(hist, xc, xp, rest, adj, cn, cc, ctri, sn, sc, pm, xa[:, t + 1])
            xn = pinned(xn, t)
            roll.append(xn[0].numpy())
            xp, xc = xc, xn
    save = lambda n, a, dt="<f4": np.save(os.path.join(out_dir, n + ".npy"), np.ascontiguousarray(a, dtype=dt))  # noqa: E731
    if seq_arrays:
        save("rest", seq.rest)
        save("faces", seq.faces, "<u4")
        save("gt_pos", x)
        if c is not None:
            save("cfaces", seq.cfaces, "<u4")
            save("c_pos", c)
    save("tf_frames", np.array(frames), "<u4")
    save("tf_pred", np.stack(tf))
    save("rollout", np.stack(roll))
    err = np.linalg.norm(np.stack(roll) - x[2:T], axis=-1).mean() * 100
    print(f"golden: {len(frames)} teacher-forced frames, {len(roll)}-frame rollout (MVE vs GT {err:.3f} cm) "
          f"-> {out_dir}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ckpt", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--name", default="")
    ap.add_argument("--golden", default=None, help="folder for golden tensors")
    ap.add_argument("--golden-seq", default=None, help="sequence folder the golden tensors come from")
    ap.add_argument("--tf-frames", default="1,2,5,10,20,40")
    ap.add_argument("--rollout", type=int, default=50)
    ap.add_argument("--golden-preds-only", action="store_true",
                    help="write only tf_frames, tf_pred and rollout (the test reads the sequence's own arrays)")
    ap.add_argument("--slim-ckpt", default=None,
                    help="also write weights + config + step (no optimiser state) here; train.py --resume "
                         "continues from it with a fresh optimiser")
    a = ap.parse_args()
    torch.set_num_threads(1)
    model, st = load_model(a.ckpt)
    tensors = export_tensors(model)
    meta = model.metadata(a.name)
    meta["train_steps"] = str(st.get("step", 0))
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    write_safetensors(a.out, tensors, meta)
    back, _ = read_safetensors(a.out)
    assert all(np.array_equal(back[k], tensors[k]) for k in tensors)
    n = sum(v.size for v in tensors.values())
    print(f"wrote {a.out}: {len(tensors)} tensors, {n} parameters, {os.path.getsize(a.out)} bytes")
    if a.slim_ckpt:
        torch.save({"model": model.state_dict(), "config": st["config"], "step": st.get("step", 0),
                    "elapsed": st.get("elapsed", 0.0)}, a.slim_ckpt)
        print(f"wrote {a.slim_ckpt}: {os.path.getsize(a.slim_ckpt)} bytes")
    if a.golden:
        golden(model, Sequence(a.golden_seq), a.golden, [int(t) for t in a.tf_frames.split(",")], a.rollout,
               seq_arrays=not a.golden_preds_only)


if __name__ == "__main__":
    main()
