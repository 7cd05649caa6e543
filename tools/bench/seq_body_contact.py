#!/usr/bin/env python3
"""Per frame of a simgen sequence: how many pairs of collider triangles intersect each other (the
skinned avatar's self-contact, e.g. the arms folded into the chest) and the largest collider vertex
step from the previous frame (how fast the fastest limb moves).

    /usr/bin/python3 tools/bench/seq_body_contact.py data/refsim/garment_1k_0064 [--every N]

Uses weft's exact triangle tests through the ctypes binding (tools/train/weft_ccd.py); triangles
sharing a vertex are not tested. Sequences made with --no-validate keep their arrays even when the
validator would reject them, so a rejected scene can be inspected this way.
"""
import argparse
import ctypes
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "train"))
from weft_ccd import CCDWorld  # noqa: E402


class _Intersections(ctypes.Structure):
    _fields_ = [("cloth_cloth", ctypes.c_uint32), ("cloth_collider", ctypes.c_uint32)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("seq")
    ap.add_argument("--every", type=int, default=1, help="check every N-th frame")
    a = ap.parse_args()
    pos = np.load(os.path.join(a.seq, "collider_pos.npy"))
    faces = np.load(os.path.join(a.seq, "collider_faces.npy"))
    world = CCDWorld(faces, pos.shape[1])  # the collider as the "cloth": its self pairs are tested
    print("frame  self-intersecting pairs  largest step (mm)")
    for f in range(0, pos.shape[0], max(1, a.every)):
        x = np.ascontiguousarray(pos[f], dtype=np.float32)
        out = _Intersections()
        rc = world._lib.weft_ccd_intersect_frame(world._world, ctypes.c_void_p(x.ctypes.data), None, ctypes.byref(out))
        if rc != 0:
            sys.exit(f"seq_body_contact: weft_ccd_intersect_frame failed ({rc})")
        step = 0.0 if f == 0 else 1000.0 * float(np.linalg.norm(pos[f] - pos[f - 1], axis=1).max())
        print(f"{f:5d}  {out.cloth_cloth:23d}  {step:17.1f}")
    world.close()


if __name__ == "__main__":
    main()
