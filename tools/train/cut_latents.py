"""Cut a trained ClothTransformer to fewer latent queries (K) without retraining.

Nothing but the learned queries depends on K (the cross-attentions and the temporal transformer
take any number of latents), so a K' < K model is the same network with K' of the queries. They
are picked by farthest-point sampling in query space (the most distinct ones first). The result
is a checkpoint for export.py, or a starting point for `train.py --init-from` (fine-tuning at K').

  /usr/bin/python3 tools/train/cut_latents.py --ckpt tools/train/models/game.ckpt.pt --k 16 \
      --out data/klevels/game_k16_init.ckpt.pt
"""
import argparse
import os
import sys

import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from model import ClothTransformer  # noqa: E402


def farthest_queries(q, k):
    """Indices (sorted) of k rows of q chosen greedily, each farthest from those already chosen."""
    idx = [int(q.norm(dim=1).argmax())]
    d = (q - q[idx[0]]).norm(dim=1)
    while len(idx) < k:
        i = int(d.argmax())
        idx.append(i)
        d = torch.minimum(d, (q - q[i]).norm(dim=1))
    return sorted(idx)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ckpt", required=True)
    ap.add_argument("--k", type=int, required=True)
    ap.add_argument("--out", required=True)
    a = ap.parse_args()
    try:
        st = torch.load(a.ckpt, map_location="cpu", weights_only=False)
    except TypeError:
        st = torch.load(a.ckpt, map_location="cpu")
    q = st["model"]["queries"]
    if not 1 <= a.k <= q.shape[0]:
        sys.exit(f"--k must be in [1, {q.shape[0]}] (the checkpoint's K)")
    idx = farthest_queries(q, a.k)
    sd = dict(st["model"])
    sd["queries"] = q[idx].clone()
    cfg = dict(st["config"])
    cfg["K"] = a.k
    ClothTransformer(cfg).load_state_dict(sd)  # the cut model must load as it is
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    torch.save({"model": sd, "config": cfg, "step": 0, "elapsed": 0.0}, a.out)
    print(f"K {q.shape[0]} -> {a.k}: queries {idx} -> {a.out}")


if __name__ == "__main__":
    main()
