"""Cut a small test sequence out of a simgen sequence: --frames frames from --start (default the
first), the collider cropped to the triangles the model's crop can ever keep (pack.crop_support), and
the pin masks when the sequence has them, in the simgen layout.

  /usr/bin/python3 tools/train/cut_seq.py --seq data/refsim/garment_1k_0053 --frames 16 \
      --out tests/model/data/garment_seq
  build/bin/weft eval --seq tests/model/data/garment_seq --method lbs --ccd off --write-pos /tmp/skin \
      && cp /tmp/skin/garment_seq.npy tests/model/data/garment_seq/skin_pos.npy

The second line adds the S track of the skinned prior (data.py); the C runtime recomputes the
same binding, so the parity goldens made from it (export.py --golden) test the runtime's S too.
Those goldens, for tests/model/test_forward.c (skinned_teacher_forced_parity,
skinned_rollout_parity), from the tiny skinned-prior model data/runs/golden_skin (train.py
--preset golden --config '{"prior":"skinned"}', 300 steps):

  /usr/bin/python3 tools/train/export.py --ckpt data/runs/golden_skin/ckpt.pt \
      --out tests/model/data/garment_seq/golden_skin.safetensors --name golden_skin \
      --golden tests/model/data/garment_seq/golden --golden-seq tests/model/data/garment_seq \
      --tf-frames 1,2,5,10 --rollout 14 --golden-preds-only

golden/ then holds only tf_frames, tf_pred and rollout; the test reads the rest from this folder.
"""
import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import data as weft_data  # noqa: E402
from pack import crop_collider  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seq", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--start", type=int, default=0, help="first frame kept")
    ap.add_argument("--crop-margin", type=float, default=0.15)
    a = ap.parse_args()
    s = weft_data.Sequence(a.seq)
    if not 0 <= a.start < s.frames:
        sys.exit(f"--start {a.start}: the sequence has {s.frames} frames")
    T = min(a.frames, s.frames - a.start)
    cut = slice(a.start, a.start + T)
    pos = np.asarray(s.pos[cut], dtype=np.float32)
    os.makedirs(a.out, exist_ok=True)
    np.save(os.path.join(a.out, "cloth_pos.npy"), pos)
    np.save(os.path.join(a.out, "rest_pos.npy"), s.rest.astype(np.float32))
    np.save(os.path.join(a.out, "faces.npy"), s.faces.astype(np.int32))
    meta = dict(s.meta)
    meta["frames"] = T
    meta["cut_from"] = {"sequence": s.name, "start": a.start, "frames": T, "collider_crop_margin_m": a.crop_margin}
    if s.pinned is not None:
        np.save(os.path.join(a.out, "pinned.npy"), (np.asarray(s.pinned[cut]) != 0).astype(np.uint8))
    if s.cpos is not None:
        cpos, cfaces, kept = crop_collider(pos, np.asarray(s.cpos[cut], dtype=np.float32), s.cfaces, a.crop_margin)
        np.save(os.path.join(a.out, "collider_pos.npy"), cpos)
        np.save(os.path.join(a.out, "collider_faces.npy"), cfaces)
        meta["cut_from"]["collider_triangles_kept"] = [int(kept), int(len(s.cfaces))]
    with open(os.path.join(a.out, "meta.json"), "w") as f:
        json.dump(meta, f, indent=1)
    print(f"{a.out}: {T} frames, {pos.shape[1]} vertices"
          + (f", collider {meta['cut_from']['collider_triangles_kept'][0]} triangles" if s.cpos is not None else ""))


if __name__ == "__main__":
    main()
