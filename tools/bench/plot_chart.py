#!/usr/bin/python3
"""Draws docs/img/chart.png from the CSV written by `weft bench chart`.

One panel per scenario: ms/frame on a log x axis against error (MVE in cm; e3D for the FNOpt
grid scenes), one labelled marker per method, the Pareto front as a step line, and methods that
produced NaN or exploded drawn as red crosses pinned to the top of the panel.
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

FAMILY_STYLE = {
    "lbs": ("#7f7f7f", "s"),
    "xpbd": ("#1f77b4", "o"),
    "xpbd-fast": ("#17becf", "v"),
    "model": ("#2ca02c", "D"),
    "fnopt": ("#9467bd", "^"),
}


def num(s):
    try:
        v = float(s)
    except (TypeError, ValueError):
        return math.nan
    return v


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--csv", required=True)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    with open(args.csv, newline="") as f:
        rows = list(csv.DictReader(f))
    scenarios = []
    for r in rows:
        if r["scenario"] not in scenarios:
            scenarios.append(r["scenario"])
    if not scenarios:
        raise SystemExit("plot_chart.py: no rows in " + args.csv)
    n = len(scenarios)
    fig, axes = plt.subplots(1, n, figsize=(6.2 * n, 5.2), squeeze=False)
    for ax, sc in zip(axes[0], scenarios):
        fn = any(r["family"] == "fnopt" for r in rows if r["scenario"] == sc)
        ekey = "e3d" if fn else "mve_cm"
        pts, bad = [], []
        for r in rows:
            if r["scenario"] != sc:
                continue
            ms, err = num(r["ms_per_frame"]), num(r[ekey])
            failed = int(r["failed_runs"] or 0) >= int(r["sequences"] or 1)
            broken = int(r["nan_runs"] or 0) > 0
            if failed or not (ms > 0) or not math.isfinite(err):
                continue
            (bad if broken else pts).append((ms, err, r))
        ymax = max([p[1] for p in pts] + [1e-9])
        # Labels only where they carry the story (baselines and the Pareto front): the learned
        # variants off the front are identified by marker style and the legend.
        on_front = {r["method"] for r in rows if r["scenario"] == sc and r.get("pareto") == "1"}
        for ms, err, r in pts:
            color, marker = FAMILY_STYLE.get(r["family"], ("k", "o"))
            ls = "none"
            face = color if r["ccd"] == "on" or r["family"] == "fnopt" else "white"
            ax.plot(ms, err, marker=marker, color=color, markerfacecolor=face, markersize=9, linestyle=ls,
                    markeredgewidth=1.6)
            label = r["method"]
            if int(r["exploded_runs"] or 0) > 0:
                # Measured, but an edge stretched or compressed by more than 25%: ring it in red.
                ax.plot(ms, err, marker="o", color="#d62728", markerfacecolor="none", markersize=16,
                        linestyle="none", markeredgewidth=1.5)
                label += f" (strain {100 * num(r['max_edge_strain']):.0f}%)"
            if r["family"] != "model" or r["method"] in on_front:
                ax.annotate(label, (ms, err), textcoords="offset points", xytext=(6, 5), fontsize=8,
                            color="#d62728" if int(r["exploded_runs"] or 0) > 0 else "black")
        # Broken methods: a red cross at the top of the panel, labelled with what failed.
        top = ymax * 1.25 if pts else 1.0
        for ms, err, r in bad:
            what = "NaN"
            ax.plot(ms, top, marker="X", color="#d62728", markersize=11, linestyle="none")
            ax.annotate(f"{r['method']} ({what})", (ms, top), textcoords="offset points", xytext=(6, -12),
                        fontsize=8, color="#d62728")
        # Pareto front: sorted by time, keep each point more accurate than every faster one.
        front, best = [], math.inf
        for ms, err, r in sorted(pts, key=lambda p: (p[0], p[1])):
            if err < best:
                front.append((ms, err))
                best = err
        if len(front) > 1:
            xs = [p[0] for p in front]
            ys = [p[1] for p in front]
            ax.step(xs, ys, where="post", color="#ff7f0e", linewidth=2, alpha=0.8, label="Pareto front")
        for fam, name in (("lbs", "LBS"), ("xpbd", "XPBD"), ("xpbd-fast", "XPBD fast (game collisions)"),
                          ("model", "learned model"), ("fnopt", "FNOpt grid")):
            if any(r["family"] == fam for _, _, r in pts + bad):
                color, marker = FAMILY_STYLE[fam]
                ax.plot([], [], marker=marker, color=color, linestyle="none", label=name)
        ax.legend(loc="upper right", fontsize=8)
        ax.set_xscale("log")
        ax.set_xlabel("ms per frame (log scale)  →  slower")
        ax.set_ylabel("e3D vs XPBD reference (relative)" if fn else "mean vertex error (cm)  →  worse")
        ax.set_title(sc)
        ax.set_ylim(bottom=0, top=top * 1.12 if (pts or bad) else 1.0)
        ax.grid(True, which="both", alpha=0.3)
        ax.text(0.01, 0.01, "better: bottom left", transform=ax.transAxes, fontsize=8, color="#555555")
    fig.suptitle("weft: speed against accuracy (filled marker = CCD on, hollow = CCD off, red X = NaN, red ring = over 1% of edges strained > 25%)",
                 fontsize=11)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)


if __name__ == "__main__":
    main()
