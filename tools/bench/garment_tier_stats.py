#!/usr/bin/env python3
"""Summary of a simgen set's garment sequences: acceptance per garment kind (first round, gentle
retry, S = 80), the rejections with where they failed, the share of frames that took more than the
attempt's substeps (fast-collider frames), and the simulation + validation time, optionally against
an earlier set with the same names.

    /usr/bin/python3 tools/bench/garment_tier_stats.py data/refsim --tier 1k [--compare data/refsim_garment_v1]
"""
import argparse
import collections
import glob
import json
import os

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("data")
    ap.add_argument("--compare", help="an earlier set: its time and acceptance on the same names")
    ap.add_argument("--tier", default="*", help="only garment_<TIER>_* (1k, 4k, 16k; default: every tier)")
    a = ap.parse_args()
    names, accepted, gentle = collections.Counter(), collections.Counter(), collections.Counter()
    at80 = raised = frames = max_s = 0
    seconds = seconds_old = 0.0
    rejected, old_accepted = [], 0
    for d in sorted(glob.glob(os.path.join(a.data, f"garment_{a.tier}_*"))):
        m = json.load(open(os.path.join(d, "meta.json")))
        kind = m["description"].split()[1]
        names[kind] += 1
        seconds += m["timings"]["simulate_s"] + m["timings"]["validate_s"]
        if m["accepted"]:
            accepted[kind] += 1
            gentle[kind] += bool(m["garment"].get("gentle_retry"))
            at80 += m["substeps"] == 80
            st = np.load(os.path.join(d, "stats.npy"))
            raised += int((st[1:, 1] > m["substeps"]).sum())
            frames += st.shape[0] - 1
            max_s = max(max_s, int(st[:, 1].max()))
        else:
            v = m["validator"]
            rejected.append((os.path.basename(d), kind, m["garment"]["motion"], v["first_hit_frame"],
                             v.get("first_hit", {}).get("body_joint")))
        if a.compare:
            o = json.load(open(os.path.join(a.compare, os.path.basename(d), "meta.json")))
            seconds_old += o["timings"]["simulate_s"] + o["timings"]["validate_s"]
            old_accepted += bool(o["accepted"])
    print("names", dict(names), "accepted", sum(accepted.values()), dict(accepted))
    print("accepted by the gentle retry", dict(gentle), "at S = 80:", at80)
    print("rejected", rejected)
    print("frames with raised substeps %d of %d (%.1f %%), most substeps in a frame %d"
          % (raised, frames, 100.0 * raised / max(frames, 1), max_s))
    print("simulate + validate: %.0f s" % seconds)
    if a.compare:
        print("earlier set, same names: %.0f s, %d accepted" % (seconds_old, old_accepted))


if __name__ == "__main__":
    main()
