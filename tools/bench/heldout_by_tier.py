"""MVE per method, scenario and resolution tier from the CSV heldout_table.py writes next to its table
(the sequence names carry the tier: garment_4k_0005), averaged weighted by frames as the table is.

  /usr/bin/python3 tools/bench/heldout_by_tier.py docs/data/heldout_test_specialists.csv
"""
import collections
import csv
import sys


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    acc = collections.defaultdict(lambda: [0.0, 0, 0])  # sum of mve * frames, frames, sequences
    for r in csv.DictReader(open(sys.argv[1])):
        key = (r["split"], r["method"], r["scenario"], r["sequence"].split("_")[1])
        acc[key][0] += float(r["mve_cm"]) * int(r["frames"])
        acc[key][1] += int(r["frames"])
        acc[key][2] += 1
    print("| split | method | scenario | tier | sequences | MVE (cm) |\n|---|---|---|---|---:|---:|")
    for (split, method, scenario, tier), (s, f, n) in sorted(acc.items()):
        print(f"| {split} | {method} | {scenario} | {tier} | {n} | {s / f:.2f} |")


if __name__ == "__main__":
    main()
