#!/usr/bin/python3
"""PyTorch eager baseline for `weft bench model`: the same ClothTransformer (tools/train/model.py)
loaded from the same safetensors file, rolled out on the same inputs, one thread, no_grad.

Inputs (written by `weft bench model` into --inputs): rest.npy (N, 3), faces.npy (F, 3),
ctri.npy (M, 3) collider triangles, colliders.npy (T, Vc, 3) collider positions per frame,
x0.npy / x1.npy the garment at frames 0 and 1. The garment is placed at frame 1; step k reads the
collider at frames 1 + k (current) and 2 + k (next), exactly as the C benchmark does.

Work kept equal to weft's step: collider triangles are cropped to the garment's box before the
collider MLP (weft crops before its MLP; the masked attention of the reference gives the same
result either way), and the decoder's rest tokens are computed once (weft precomputes them).
The decoder's query projection is still recomputed every step (the reference module has no
cache for it); weft does that once per garment.

Prints one JSON object: {"ms_per_frame": median wall ms, "cpu_ms_per_frame": median CPU ms of
the calling thread (with one thread PyTorch runs every operator on it), "frames": n, "threads": 1}.
"""
import argparse
import json
import os
import statistics
import sys
import time

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "train"))

from export import read_safetensors  # noqa: E402
from model import ClothTransformer, crop_mask, mean_adjacency  # noqa: E402


def load(path):
    tensors, meta = read_safetensors(path)
    if meta.get("precision", "fp32") != "fp32":
        raise SystemExit(f"{path}: PyTorch baseline needs the fp32 file")
    model = ClothTransformer(json.loads(meta["config"]))
    state = {k: torch.from_numpy(np.array(v)) for k, v in tensors.items()}
    model.load_state_dict(state, strict=True)
    return model.eval()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", required=True, help="fp32 safetensors file")
    ap.add_argument("--inputs", required=True, help="folder written by weft bench model")
    ap.add_argument("--frames", type=int, default=30)
    ap.add_argument("--warmup", type=int, default=5)
    a = ap.parse_args()

    torch.set_num_threads(1)
    model = load(a.model)
    d = a.inputs
    rest = torch.from_numpy(np.load(os.path.join(d, "rest.npy")))[None]
    faces = np.load(os.path.join(d, "faces.npy")).astype(np.int64)
    ctri = torch.from_numpy(np.load(os.path.join(d, "ctri.npy")).astype(np.int64))
    colliders = torch.from_numpy(np.load(os.path.join(d, "colliders.npy")))
    x_t = torch.from_numpy(np.load(os.path.join(d, "x1.npy")))[None]
    x_prev = torch.from_numpy(np.load(os.path.join(d, "x0.npy")))[None]
    # the skinned prior's S track (frames x V x 3), written beside the colliders
    skin_path = os.path.join(d, "skin.npy")
    skin = torch.from_numpy(np.load(skin_path)) if os.path.exists(skin_path) else None
    if model.cfg["prior"] == "skinned" and skin is None:
        raise SystemExit(f"the skinned prior needs {skin_path}")
    steps = a.warmup + a.frames
    if colliders.shape[0] < steps + 2:
        raise SystemExit(f"colliders.npy has {colliders.shape[0]} frames, {steps + 2} needed")
    adj = mean_adjacency(faces, rest.shape[1])
    margin = model.cfg["crop_margin"]

    times, cpu = [], []
    with torch.no_grad():
        cached = model.rest_tokens(rest)
        model.rest_tokens = lambda _rest: cached
        hist = []
        for k in range(steps):
            c_cur = colliders[1 + k][None]
            c_next = colliders[2 + k][None]
            t0, c0 = time.perf_counter(), time.thread_time()
            keep = crop_mask(x_t, c_next, ctri, margin)[0]
            tri = ctri[keep]
            s_cur = None if skin is None else skin[1 + k][None]
            s_next = None if skin is None else skin[2 + k][None]
            x_next, hist = model.step(hist, x_t, x_prev, rest, adj, c_next, c_cur, tri, s_next, s_cur)
            dc, dt = time.thread_time() - c0, time.perf_counter() - t0
            if k >= a.warmup:
                times.append(dt * 1e3)
                cpu.append(dc * 1e3)
            x_prev, x_t = x_t, x_next
    if not torch.isfinite(x_t).all():
        raise SystemExit("rollout produced NaN or infinity")
    print(json.dumps({"ms_per_frame": statistics.median(times), "cpu_ms_per_frame": statistics.median(cpu),
                      "frames": len(times), "threads": torch.get_num_threads()}))


if __name__ == "__main__":
    main()
