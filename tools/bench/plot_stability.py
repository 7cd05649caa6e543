#!/usr/bin/python3
"""Draws docs/img/stability.png from the CSV written by `weft bench stability` (docs/data/stability.csv).

A heat map, methods down, stress cases across: green pass, amber warning (penetrations, after CCD when it is on,
MVE drift, or too slow to finish), red failure (NaN, explosion, run error), grey not measured. Each cell is
annotated with the error (MVE cm, or e3D for FNOpt cells) and the first- and last-quarter MVE.
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

LEVEL = {"pass": 0, "penetrates": 1, "drifts": 1, "too slow": 1, "NaN": 2, "exploded": 2, "error": 2}
COLORS = ["#4caf50", "#ffb300", "#e53935", "#bdbdbd"]


def num(s):
    try:
        return float(s)
    except (TypeError, ValueError):
        return math.nan


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--csv", required=True)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    with open(args.csv, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        raise SystemExit("plot_stability.py: no rows in " + args.csv)
    cases, methods = [], []
    for r in rows:
        if r["case"] not in cases:
            cases.append(r["case"])
        if r["method"] not in methods:
            methods.append(r["method"])
    grid = [[3 for _ in cases] for _ in methods]
    text = [["n/a" for _ in cases] for _ in methods]
    for r in rows:
        i, j = methods.index(r["method"]), cases.index(r["case"])
        st = r["status"]
        grid[i][j] = LEVEL.get(st, 3)
        if st in ("not generated", "n/a"):
            text[i][j] = st
            continue
        if r["family"] == "fnopt":
            v = num(r["e3d"])
            t = f"e3D {v:.3f}" if math.isfinite(v) else ""
        else:
            v = num(r["mve_cm"])
            t = f"{v:.2f} cm" if math.isfinite(v) else ""
            q1, q4, g = num(r["mve_first_quarter"]), num(r["mve_last_quarter"]), num(r["mve_growth"])
            # Rollouts start from ground truth, so the first quarter is often ~0 and a ratio would
            # only amplify noise: show both quarters, and the ratio when the first is >= 0.1 cm.
            if math.isfinite(q1) and math.isfinite(q4):
                t += f"\n¼: {q1:.2f} → {q4:.2f} cm"
                if math.isfinite(g) and q1 >= 0.1:
                    t += f" ({g:.1f}x)"
        if st != "pass":
            t = st + ("\n" + t if t else "")
        text[i][j] = t
    # The method labels take their own width; with few cases (e.g. --axes long) the cells would
    # otherwise be squeezed to nothing, and the title and legend need about 8 inches.
    label_in = 0.065 * max((len(m) for m in methods), default=10)
    fig, ax = plt.subplots(figsize=(max(8.0, 1.55 * len(cases) + label_in + 1.0), 0.62 * len(methods) + 2.2))
    ax.imshow(grid, cmap=ListedColormap(COLORS), vmin=0, vmax=3, aspect="auto")
    for i in range(len(methods)):
        for j in range(len(cases)):
            ax.text(j, i, text[i][j], ha="center", va="center", fontsize=7)
    ax.set_xticks(range(len(cases)))
    ax.set_xticklabels(cases, rotation=30, ha="right", fontsize=8)
    ax.set_yticks(range(len(methods)))
    ax.set_yticklabels(methods, fontsize=8)
    ax.set_xticks([x - 0.5 for x in range(1, len(cases))], minor=True)
    ax.set_yticks([y - 0.5 for y in range(1, len(methods))], minor=True)
    ax.grid(which="minor", color="white", linewidth=2)
    ax.tick_params(which="minor", length=0)
    ax.legend(handles=[Patch(color=COLORS[0], label="pass"),
                       Patch(color=COLORS[1], label="penetrates (after CCD when on) / MVE drifts / too slow"),
                       Patch(color=COLORS[2], label="NaN / >1% of edges strained > 25% / run failed"),
                       Patch(color=COLORS[3], label="not measured")],
              loc="upper center", bbox_to_anchor=(0.5, -0.18), ncol=2, fontsize=8, frameon=False)
    ax.set_title("weft stability: where each method fails (cell: status, MVE, first/last-quarter MVE)", fontsize=10)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110, bbox_inches="tight")  # the legend sits below the axes


if __name__ == "__main__":
    main()
