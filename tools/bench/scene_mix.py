"""Frame-weighted MVE of a per-scene choice of methods, from the per-sequence CSVs that
heldout_table.py writes: each scenario's rows come from the (CSV, method) named for it.

  /usr/bin/python3 tools/bench/scene_mix.py \
      --scene drop=docs/data/heldout_test_specialists.csv:specialists \
      --scene garment=docs/data/heldout_test_specialists.csv:specialists \
      --scene gripper=docs/data/heldout_test_gripper.csv:gripper

prints the mean of every scenario and of all of them together (the `all` column of heldout_table.py:
MVE weighted by scored frames), so a table measured per scene can be combined without running the
whole split again. A sequence listed twice for one scenario is an error.
"""
import argparse
import csv
import sys


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scene", action="append", required=True, metavar="SCENARIO=CSV:METHOD")
    ap.add_argument("--split", default="test")
    a = ap.parse_args()
    total_w = total = 0.0
    for spec in a.scene:
        scenario, _, rest = spec.partition("=")
        path, _, method = rest.rpartition(":")
        if not scenario or not path or not method:
            sys.exit(f"--scene {spec}: expected SCENARIO=CSV:METHOD")
        with open(path, newline="") as f:
            rows = [r for r in csv.DictReader(f)
                    if r["method"] == method and r["scenario"] == scenario and r["split"] == a.split]
        names = [r["sequence"] for r in rows]
        if len(set(names)) != len(names):
            sys.exit(f"{path}: method {method} lists a {scenario} sequence twice")
        if not rows:
            sys.exit(f"{path}: no {a.split} rows of method {method} on {scenario}")
        w = sum(float(r["frames"]) for r in rows)
        s = sum(float(r["mve_cm"]) * float(r["frames"]) for r in rows)
        print(f"{scenario:8s} {method:20s} {s / w:7.2f} cm ({len(rows)} sequences, {path})")
        total_w += w
        total += s
    print(f"{'all':8s} {'':20s} {total / total_w:7.2f} cm")


if __name__ == "__main__":
    main()
