"""Roll out a prior alone (no network) and report its MVE, per sequence and in all.

  /usr/bin/python3 tools/train/prior_eval.py --data data/pack --split test val

Priors:
  still     X_{t+1} = X_t (the cloth does not move: the ballistic prior at beta 0, no gravity)
  inertial  X_{t+1} = 2 X_t - X_{t-1} (the ballistic prior at beta 1, no gravity)
  ballistic X_{t+1} = X_t + beta (X_t - X_{t-1}) - g dt^2 y (free fall through everything; the
            runtime's ballistic prior, --beta as its prior_beta)
  translate X_t + the mean step of the vertices pinned at t+1 to their targets (with --pins;
            without pins X_t + beta (X_t - X_{t-1}))
  grasp     X_t + beta (X_t - X_{t-1}), each vertex then kept within its rest distance of the
            centroid of the pins' targets (the runtime's grasp prior, --beta as its prior_beta;
            with --pins)
  follow    each vertex moves with the closest point of the collider (nearest triangle at t, same
            barycentric point at t+1), weighted by 1 - distance / --radius, and keeps its
            velocity for the rest of the weight (the collider-following prior)
still, inertial, ballistic and grasp are computed by model.py's prior_positions, the priors the
runtime implements. The rollout starts from ground-truth frames 0 and 1 and then sees only the collider, as `weft eval`;
with --pins the vertices pinned in a frame (pinned.npy) take their reference positions, as `weft eval
--pins all`:

  /usr/bin/python3 tools/train/prior_eval.py --data data/grippers --split test --pins \
      --priors still,translate,grasp --beta 0.9
These numbers say how much a learned model must add to its prior.
"""
import argparse
import os
import sys

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import data as weft_data  # noqa: E402
from model import full_config, prior_positions  # noqa: E402


def closest_barycentric(p, a, b, c):
    """Barycentric coordinates (N, 3) of the closest point of triangles abc to points p (Ericson,
    Real-Time Collision Detection 5.1.5, region by region)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    vc = d1 * d4 - d3 * d2
    vb = d5 * d2 - d1 * d6
    va = d3 * d6 - d5 * d4
    n = len(p)
    out = np.zeros((n, 3))
    done = np.zeros(n, bool)

    def put(mask, bary):
        m = mask & ~done
        out[m] = bary[m]
        done[m] = True

    one = np.ones(n)
    zero = np.zeros(n)
    safe = lambda x: np.where(np.abs(x) < 1e-300, 1e-300, x)  # noqa: E731
    put((d1 <= 0) & (d2 <= 0), np.stack([one, zero, zero], 1))
    put((d3 >= 0) & (d4 <= d3), np.stack([zero, one, zero], 1))
    put((d6 >= 0) & (d5 <= d6), np.stack([zero, zero, one], 1))
    v = d1 / safe(d1 - d3)
    put((vc <= 0) & (d1 >= 0) & (d3 <= 0), np.stack([1 - v, v, zero], 1))
    w = d2 / safe(d2 - d6)
    put((vb <= 0) & (d2 >= 0) & (d6 <= 0), np.stack([1 - w, zero, w], 1))
    w = (d4 - d3) / safe((d4 - d3) + (d5 - d6))
    put((va <= 0) & ((d4 - d3) >= 0) & ((d5 - d6) >= 0), np.stack([zero, 1 - w, w], 1))
    den = safe(va + vb + vc)
    v, w = vb / den, vc / den
    put(np.ones(n, bool), np.stack([1 - v - w, v, w], 1))
    return out


def follow_displacement(x, c_now, c_next, faces, candidates=8):
    """Per vertex: displacement of its closest collider point from t to t+1, and the distance."""
    tri = c_now[faces]
    cen = tri.mean(axis=1)
    d2 = ((x[:, None, :] - cen[None, :, :]) ** 2).sum(-1)
    k = min(candidates, len(faces))
    near = np.argpartition(d2, k - 1, axis=1)[:, :k]
    best_d = np.full(len(x), np.inf)
    best_disp = np.zeros_like(x)
    for j in range(k):
        idx = near[:, j]
        t = tri[idx]
        bary = closest_barycentric(x, t[:, 0], t[:, 1], t[:, 2])
        q = (bary[:, :, None] * t).sum(1)
        dist = np.linalg.norm(x - q, axis=1)
        disp = (bary[:, :, None] * c_next[faces[idx]]).sum(1) - q
        m = dist < best_d
        best_d[m] = dist[m]
        best_disp[m] = disp[m]
    return best_disp, best_d


# The analysis priors that are runtime priors, as model configs (prior_beta from --beta where None).
RUNTIME_PRIORS = {
    "still": {"prior": "ballistic", "prior_beta": 0.0, "gravity_step": 0.0},
    "inertial": {"prior": "ballistic", "prior_beta": 1.0, "gravity_step": 0.0},
    "ballistic": {"prior": "ballistic", "prior_beta": None},
    "grasp": {"prior": "grasp", "prior_beta": None},
}


def runtime_prior(prior, beta, xt, xp, pm, pin_next, rest):
    """One frame of a runtime prior (numpy float64 in and out)."""
    cfg = dict(RUNTIME_PRIORS[prior])
    cfg["prior_beta"] = beta if cfg["prior_beta"] is None else cfg["prior_beta"]
    t = lambda a: None if a is None else torch.from_numpy(np.asarray(a)).unsqueeze(0)  # noqa: E731
    return prior_positions(full_config(cfg), t(xt), t(xp), pin_mask=t(pm), pin_next=t(pin_next),
                           rest=t(rest))[0].numpy()


def rollout(seq, prior, radius, frames, beta=1.0, pins=False):
    x = np.asarray(seq.pos, dtype=np.float64)
    rest = np.asarray(seq.rest, dtype=np.float64)
    pinned = np.asarray(seq.pinned) != 0 if pins and seq.pinned is not None else None
    T = min(frames, len(x))
    c = None if seq.cpos is None else np.asarray(seq.cpos, dtype=np.float64)
    pred = [x[0], x[1]]
    for t in range(1, T - 1):
        xt, xp = pred[-1], pred[-2]
        vel = xt - xp
        pm = None if pinned is None or not pinned[t + 1].any() else pinned[t + 1]
        if prior == "translate":
            nxt = xt + (x[t + 1][pm] - xt[pm]).mean(axis=0) if pm is not None else xt + beta * vel
        elif prior in RUNTIME_PRIORS or c is None:
            nxt = runtime_prior(prior if prior in RUNTIME_PRIORS else "inertial", beta, xt, xp, pm, x[t + 1], rest)
        else:
            disp, dist = follow_displacement(xt, c[t], c[t + 1], seq.cfaces)
            w = np.clip(1.0 - dist / radius, 0.0, 1.0)[:, None]
            nxt = xt + w * disp + (1.0 - w) * vel
        if pm is not None:
            nxt = np.where(pm[:, None], x[t + 1], nxt)
        pred.append(nxt)
    pred = np.asarray(pred)
    return float(np.linalg.norm(pred[2:T] - x[2:T], axis=-1).mean() * 100.0), T - 2


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", nargs="+", required=True)
    ap.add_argument("--split", nargs="+", default=["test"])
    ap.add_argument("--priors", default="still,inertial,follow")
    ap.add_argument("--radius", type=float, default=0.05, help="follow prior: influence radius (m)")
    ap.add_argument("--frames", type=int, default=240)
    ap.add_argument("--beta", type=float, default=1.0,
                    help="ballistic, translate and grasp priors: velocity factor")
    ap.add_argument("--pins", action="store_true", help="pinned vertices follow the reference")
    a = ap.parse_args()
    seqs = [s for s in weft_data.load_sequences(a.data) if s.split in a.split]
    if not seqs:
        sys.exit(f"no sequences of split {a.split} under {a.data}")
    for prior in a.priors.split(","):
        if prior not in RUNTIME_PRIORS and prior not in ("translate", "follow"):
            sys.exit(f"unknown prior {prior!r}: still, inertial, ballistic, grasp, translate or follow")
        rows = [(s.name, *rollout(s, prior, a.radius, a.frames, a.beta, a.pins)) for s in seqs]
        total = sum(m * n for _, m, n in rows) / sum(n for _, _, n in rows)
        print(f"{prior:9s} all {total:7.2f} cm | " + "  ".join(f"{n} {m:.2f}" for n, m, _ in rows), flush=True)


if __name__ == "__main__":
    main()
