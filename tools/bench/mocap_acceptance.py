#!/usr/bin/env python3
"""What the reference's validator kept of a real-motion simgen set (`weft simgen --mocap`): the
windows accepted whole and as their first frames, the frames kept of those planned (in all, per
garment kind), and two markdown tables: the first window of each clip with the rejecting frame
and its reason, and every window per clip.

    /usr/bin/python3 tools/bench/mocap_acceptance.py data/evalset

A window's planned frames are meta.json's `planned_frames` when it was cut short, else its
`frames` (a rejected window records the frames it was planned with). Frames of the rejecting hit
count from the start of the pre-roll (`validator.first_hit_frame`).
"""
import argparse
import collections
import glob
import json
import os
import re
import sys

import numpy as np

KIND_NAMES = {"tshirt": "T-shirt", "skirt": "skirt", "dress": "dress"}
PLURAL = {"tshirt": "T-shirts", "skirt": "skirts", "dress": "dresses"}


def load(data):
    wins = []
    for meta in sorted(glob.glob(os.path.join(data, "mocap_*", "meta.json"))):
        with open(meta) as f:
            m = json.load(f)
        if "mocap" not in m:
            continue
        kind = re.match(r"garment: (\w+) on", m.get("description", ""))
        planned = m.get("planned_frames") or m["frames"]
        accepted = bool(m["accepted"])
        wins.append({"dir": os.path.dirname(meta), "columns": m.get("stats_columns", []),
                     "clip": m["mocap"]["clip"], "start_s": float(m["mocap"]["start_s"]),
                     "kind": kind.group(1) if kind else "?", "planned": int(planned),
                     "kept": int(m["frames"]) if accepted else 0, "accepted": accepted,
                     "truncated": bool(m.get("truncated")), "substeps": m.get("substeps"),
                     "validator": m.get("validator", {}), "mocap": m["mocap"]})
    return wins


def reason(w):
    v, mo = w["validator"], w["mocap"]
    f = v.get("first_hit_frame", -1)
    if mo.get("tangled_rejected"):
        where = " outside a pinch" if "tangled_clear_max" in mo else ""
        return f"{f}: {100 * mo.get('rejected_share', 0):.1f} % of the cloth crossing itself{where}"
    if mo.get("inside_clear_rejected"):
        return f"{f}: {100 * mo.get('rejected_share', 0):.1f} % of the cloth inside the body where it is clear"
    joint = (v.get("first_hit") or {}).get("body_joint")
    return f"{f}: cloth crossed itself" + (f" (near {joint})" if joint else "")


def kept_cell(w):
    if w["accepted"] and not w["truncated"]:
        return f"all {w['kept']}"
    return f"first {w['kept']} of {w['planned']}" if w["accepted"] else "none"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("data")
    a = ap.parse_args()
    wins = load(a.data)
    if not wins:
        sys.exit(f"mocap_acceptance: no real-motion sequence (meta.json with a mocap block) under {a.data}")
    whole = [w for w in wins if w["accepted"] and not w["truncated"]]
    trunc = [w for w in wins if w["truncated"]]
    kept, planned = sum(w["kept"] for w in wins), sum(w["planned"] for w in wins)
    print(f"{len(whole)} of {len(wins)} windows accepted whole and {len(trunc)} as their first frames: "
          f"{kept:,} of {planned:,} frames ({100 * kept / planned:.0f} %); the whole windows "
          f"{sum(w['kept'] for w in whole):,} frames ({100 * sum(w['kept'] for w in whole) / planned:.0f} %)")
    for k in ("skirt", "dress", "tshirt"):
        sub = [w for w in wins if w["kind"] == k]
        if sub:
            kk, pp = sum(w["kept"] for w in sub), sum(w["planned"] for w in sub)
            print(f"  {PLURAL[k]}: {kk:,} of {pp:,} frames ({100 * kk / pp:.0f} %), "
                  f"{sum(w['kept'] > 0 for w in sub)} of {len(sub)} windows keep frames")
    stops = collections.Counter()
    for w in wins:
        if not (w["accepted"] and not w["truncated"]):
            mo = w["mocap"]
            stops["a tangle past the limit" if mo.get("tangled_rejected") else
                  "cloth inside the body where it is clear" if mo.get("inside_clear_rejected") else
                  "a swept crossing"] += 1
    print("cut short or rejected at: " + ", ".join(f"{n} {what}" for what, n in stops.most_common()))
    joints = collections.Counter((w["validator"].get("first_hit") or {}).get("body_joint") for w in wins
                                 if not (w["accepted"] and not w["truncated"]) and not w["mocap"].get("tangled_rejected")
                                 and not w["mocap"].get("inside_clear_rejected"))
    if joints:
        print("  swept crossings, nearest joint: " + ", ".join(f"{j} {n}" for j, n in joints.most_common()))
    # the accepted frames' stats rows (row 0 is the initial state), per garment kind; a column an
    # older set lacks is left out
    for k in ("tshirt", "dress", "skirt"):
        cols = collections.defaultdict(list)
        for w in wins:
            if w["kind"] == k and w["accepted"]:
                st = np.load(os.path.join(w["dir"], "stats.npy"))[1:]
                for name in ("tangled", "tangled_clear", "inside_clear"):
                    if name in w["columns"]:
                        cols[name].append(st[:, w["columns"].index(name)])
        if "tangled" not in cols:
            continue
        t = np.concatenate(cols["tangled"])
        line = (f"  {PLURAL[k]}, accepted frames: crossing itself in {100 * (t > 0).mean():.0f} % of them, "
                f"{100 * t.mean():.2f} % of the cloth on average, {100 * t.max():.2f} % at worst")
        if cols["tangled_clear"]:
            tc = np.concatenate(cols["tangled_clear"])
            line += f" (outside a pinch {100 * tc.mean():.2f} %, {100 * tc.max():.2f} % at worst)"
        line += f"; inside where the body is clear {100 * np.concatenate(cols['inside_clear']).max():.2f} % at worst"
        print(line)

    print("\n| clip | garment | kept | the rejecting frame and why, or the accepted window |\n|---|---|---|---|")
    firsts = {}
    for w in wins:
        if w["clip"] not in firsts or w["start_s"] < firsts[w["clip"]]["start_s"]:
            firsts[w["clip"]] = w
    for w in sorted(firsts.values(), key=lambda w: wins.index(w)):
        mo = w["mocap"]
        why = (f"{w['substeps']} substeps; exempt {100 * mo.get('self_exempt_mean', 0):.1f} % of the cloth on "
               f"average, crossing itself {100 * mo.get('tangled_max', 0):.2f} % at worst"
               + (f" ({100 * mo['tangled_clear_max']:.2f} % outside a pinch)" if "tangled_clear_max" in mo else "")
               if w["accepted"] and not w["truncated"] else reason(w))
        print(f"| {w['clip']} | {KIND_NAMES.get(w['kind'], w['kind'])} | {kept_cell(w)} | {why} |")

    print("\n| clip | windows | whole | first frames only | kept frames | windows (start, garment, frames kept) |")
    print("|---|---:|---:|---:|---:|---|")
    by_clip = collections.defaultdict(list)
    for w in wins:
        by_clip[w["clip"]].append(w)
    for clip in sorted(by_clip):
        ws = sorted(by_clip[clip], key=lambda w: w["start_s"])
        cells = []
        for w in ws:
            c = f"{w['start_s']:g} s {KIND_NAMES.get(w['kind'], w['kind'])}"
            if w["accepted"]:
                c += f" **{'all ' if not w['truncated'] else ''}{w['kept']}**"
            cells.append(c)
        print(f"| {clip} | {len(ws)} | {sum(w['accepted'] and not w['truncated'] for w in ws)} | "
              f"{sum(w['truncated'] for w in ws)} | {sum(w['kept'] for w in ws)} of {sum(w['planned'] for w in ws)} | "
              + ", ".join(cells) + " |")


if __name__ == "__main__":
    main()
