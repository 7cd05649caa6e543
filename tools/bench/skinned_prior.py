"""Priors alone on held-out sequences: LBS, the skinned prior and the `previous` prior.

  /usr/bin/python3 tools/bench/skinned_prior.py --data data/refsim --split test val

S is the LBS method's rollout (`weft eval --method lbs --ccd off --write-pos`, the binding the
LBS method and the tethers use). Rolled out from reference frames 0 and 1 with no network:
  LBS       X_t = S_t
  skinned   X_t = X_1 + S_t - S_1      (X_{t+1} = X_t + S_{t+1} - S_t)
  previous  X_t = X_1
MVE in cm over frames 2.. (as `weft eval`), per sequence, then per scenario (mean of sequences).
A second table gives, per scenario, how far the reference lies from the skinned garment, |X_t - S_t|
over every vertex of frames 1.. (percentiles in cm): what a tether of a given radius would cut off.
"""
import argparse
import glob
import os
import subprocess
import sys
import tempfile

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weft", default="build/bin/weft")
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", nargs="+", default=["test"])
    a = ap.parse_args()
    priors = ("lbs", "skinned", "previous")
    per_scenario = {}
    offsets = {}
    with tempfile.TemporaryDirectory() as tmp:
        for split in a.split:
            cmd = [a.weft, "eval", "--seq", a.data, "--split", split, "--method", "lbs", "--ccd", "off",
                   "--write-pos", tmp]
            if subprocess.run(cmd, stdout=subprocess.DEVNULL).returncode != 0:
                sys.exit("skinned_prior: `%s` failed" % " ".join(cmd))
        for f in sorted(glob.glob(os.path.join(tmp, "*.npy"))):
            name = os.path.basename(f)[:-4]
            s = np.load(f)
            g = np.load(os.path.join(a.data, name, "cloth_pos.npy"))[:len(s)]
            tracks = {"lbs": s, "skinned": g[1] + s - s[1], "previous": np.broadcast_to(g[1], s.shape)}
            mve = {p: np.linalg.norm(tracks[p][2:] - g[2:], axis=-1).mean() * 100.0 for p in priors}
            print(f"{name:24s} " + "  ".join(f"{p} {mve[p]:6.2f}" for p in priors))
            per_scenario.setdefault(name.split("_")[0], []).append(mve)
            offsets.setdefault(name.split("_")[0], []).append(
                (np.linalg.norm(s[1:] - g[1:], axis=-1) * 100.0).astype(np.float32).ravel())
    print("\n| scenario (n) | " + " | ".join(priors) + " |\n|---|" + "---:|" * len(priors))
    for sc, rows in sorted(per_scenario.items()):
        print(f"| {sc} ({len(rows)}) | " + " | ".join(f"{np.mean([r[p] for r in rows]):.2f}" for p in priors) + " |")
    pct = (50, 75, 90, 95, 99)
    print("\n|X_t - S_t| (cm) over all vertices and frames\n\n| scenario (n) | mean | "
          + " | ".join(f"p{q}" for q in pct) + " | max |\n|---|---:|" + "---:|" * (len(pct) + 1))
    for sc, rows in sorted(offsets.items()):
        d = np.concatenate(rows)
        print(f"| {sc} ({len(rows)}) | {d.mean():.2f} | " + " | ".join(f"{v:.2f}" for v in np.percentile(d, pct))
              + f" | {d.max():.2f} |")


if __name__ == "__main__":
    main()
