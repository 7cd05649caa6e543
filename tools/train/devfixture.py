"""DEVELOPMENT FIXTURE ONLY -- not training data for shipped models.

Writes small sequences in the simgen layout (meta.json + .npy) so that the training, export and
parity pipeline can be exercised without the reference simulator: a square sheet falls onto a
(possibly moving) sphere, integrated with a position-based mass-spring scheme (Verlet, Jacobi
distance constraints, sphere push-out). The physics is deliberately simple; real training data
comes from `weft simgen` (XPBD reference simulator).

  /usr/bin/python3 tools/train/devfixture.py --out data/devfixture --count 12
"""
import argparse
import json
import os

import numpy as np


def grid_sheet(n, size):
    u = np.linspace(-size / 2, size / 2, n)
    xx, zz = np.meshgrid(u, u, indexing="ij")
    rest = np.stack([xx.ravel(), np.zeros(n * n), zz.ravel()], axis=1).astype(np.float32)
    faces = []
    for i in range(n - 1):
        for j in range(n - 1):
            a, b, c, d = i * n + j, i * n + j + 1, (i + 1) * n + j, (i + 1) * n + j + 1
            faces += [[a, c, b], [b, c, d]]
    return rest, np.array(faces, dtype=np.int32)


def uv_sphere(radius, rings=10, segs=16):
    verts = [[0, radius, 0]]
    for r in range(1, rings):
        th = np.pi * r / rings
        for s in range(segs):
            ph = 2 * np.pi * s / segs
            verts.append([radius * np.sin(th) * np.cos(ph), radius * np.cos(th), radius * np.sin(th) * np.sin(ph)])
    verts.append([0, -radius, 0])
    faces = []
    for s in range(segs):  # outward (counter-clockwise seen from outside)
        faces.append([0, 1 + (s + 1) % segs, 1 + s])
    for r in range(rings - 2):
        for s in range(segs):
            a = 1 + r * segs + s
            b = 1 + r * segs + (s + 1) % segs
            c = a + segs
            d = b + segs
            faces += [[a, b, d], [a, d, c]]
    last = len(verts) - 1
    base = 1 + (rings - 2) * segs
    for s in range(segs):
        faces.append([last, base + s, base + (s + 1) % segs])
    return np.array(verts, dtype=np.float32), np.array(faces, dtype=np.int32)


def springs(n):
    """Structural, shear and bend springs of an n x n grid as (S, 2) vertex pairs."""
    pairs = []
    for di, dj in [(0, 1), (1, 0), (1, 1), (1, -1), (0, 2), (2, 0)]:
        for i in range(n):
            for j in range(n):
                i2, j2 = i + di, j + dj
                if 0 <= i2 < n and 0 <= j2 < n:
                    pairs.append((i * n + j, i2 * n + j2))
    return np.array(pairs, dtype=np.int64)


def simulate(rng, n=16, frames=90, substeps=20, iters=4):
    rest, faces = grid_sheet(n, 0.6)
    sp = springs(n)
    rlen = np.linalg.norm(rest[sp[:, 0]] - rest[sp[:, 1]], axis=1)
    radius = rng.uniform(0.12, 0.22)
    sph_v, sph_f = uv_sphere(radius)
    # tilt and lift the sheet, place the sphere below with a random offset and drift
    ang = rng.uniform(-0.4, 0.4)
    rot = np.array([[np.cos(ang), -np.sin(ang), 0], [np.sin(ang), np.cos(ang), 0], [0, 0, 1]], np.float32)
    x = rest @ rot.T + np.array([0, rng.uniform(0.25, 0.45), 0], np.float32)
    centre0 = np.array([rng.uniform(-0.1, 0.1), 0.0, rng.uniform(-0.1, 0.1)], np.float64)
    drift = np.array([rng.uniform(-0.3, 0.3), 0.0, rng.uniform(-0.3, 0.3)])
    x = x.astype(np.float64)
    xp = x.copy()
    dt = 1.0 / 60 / substeps
    g = np.array([0, -9.81, 0])
    out_x, out_c = [], []
    for f in range(frames):
        t0 = f / 60.0
        for s in range(substeps):
            t = t0 + (s + 1) * dt
            centre = centre0 + drift * min(t, 0.6)
            v = (x - xp) * 0.999
            xp = x.copy()
            x = x + v + g * dt * dt
            for _ in range(iters):
                d = x[sp[:, 1]] - x[sp[:, 0]]
                L = np.linalg.norm(d, axis=1, keepdims=True) + 1e-12
                corr = 0.5 * (1 - rlen[:, None] / L) * d
                acc = np.zeros_like(x)
                cnt = np.zeros((len(x), 1))
                np.add.at(acc, sp[:, 0], corr)
                np.add.at(acc, sp[:, 1], -corr)
                np.add.at(cnt, sp[:, 0], 1)
                np.add.at(cnt, sp[:, 1], 1)
                x = x + 1.2 * acc / np.maximum(cnt, 1)
                rel = x - centre
                dist = np.linalg.norm(rel, axis=1, keepdims=True)
                inside = (dist < radius + 0.005)[:, 0]
                if inside.any():
                    x[inside] = centre + rel[inside] / dist[inside] * (radius + 0.005)
                    xp[inside] = x[inside] - 0.5 * (x[inside] - xp[inside])  # friction-ish
        out_x.append(x.astype(np.float32))
        out_c.append((sph_v + (centre0 + drift * min(t0 + 1 / 60, 0.6))).astype(np.float32))
    return rest, faces, np.stack(out_x), np.stack(out_c), sph_f


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="data/devfixture")
    ap.add_argument("--count", type=int, default=12)
    ap.add_argument("--frames", type=int, default=90)
    ap.add_argument("--seed", type=int, default=1)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    for i in range(a.count):
        d = os.path.join(a.out, f"sheet_sphere_{i:03d}")
        os.makedirs(d, exist_ok=True)
        rest, faces, xs, cs, cf = simulate(rng, frames=a.frames)
        np.save(os.path.join(d, "rest_pos.npy"), rest)
        np.save(os.path.join(d, "faces.npy"), faces)
        np.save(os.path.join(d, "cloth_pos.npy"), xs)
        np.save(os.path.join(d, "collider_pos.npy"), cs)
        np.save(os.path.join(d, "collider_faces.npy"), cf)
        meta = {"scenario": "devfixture", "fixture": "development only, not training data",
                "frame_dt": 1 / 60, "frames": int(xs.shape[0]), "split": "test" if i % 6 == 5 else "train"}
        with open(os.path.join(d, "meta.json"), "w") as f:
            json.dump(meta, f, indent=1)
        print(d, xs.shape, cs.shape)


if __name__ == "__main__":
    main()
