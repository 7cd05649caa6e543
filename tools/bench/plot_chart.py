#!/usr/bin/python3
"""Draws docs/img/chart.png from the CSV written by `weft bench chart` (docs/data/chart.csv).

One panel per scenario (and one for the FNOpt grid scenes, and one for real motion): ms/frame on a
log x axis against error (MVE in cm; relative e3D for FNOpt; on real motion, which has no ground
truth, the share of cloth inside the body), lower left is better. Every scored setting is a small
faint marker in its family's colour; each family (learned int8/fp16/fp32, fast XPBD, reference
XPBD, LBS, the FNOpt optimizers) gets one large marker and one label at its best setting (its
point on the Pareto front if it has one, else its lowest error). The Pareto front (lowest error
at this many ms or fewer, over the scored rows) is a step line. The axes fit the front and the
labelled points; anything beyond them is a triangle on the edge, pointing outward, with its
value. A red ring marks a labelled point where some runs exploded (on real motion: where a garment
was lost). Rows with NaN runs or no error
are not scored, only counted under their panel. The full table is the CSV.

Usage: plot_chart.py --csv docs/data/chart.csv --out docs/img/chart.png
"""
import argparse
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.legend_handler import HandlerTuple  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.transforms import Bbox  # noqa: E402
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter  # noqa: E402

# family key -> (legend name, colour, marker)
FAMILIES = {
    "learned-int8": ("learned int8", "#2ca02c", "D"),
    "learned-fp16": ("learned fp16", "#9467bd", "D"),
    "learned-fp32": ("learned fp32", "#8c564b", "D"),
    "xpbd-fast": ("fast XPBD", "#ff7f0e", "p"),
    "xpbd": ("reference XPBD", "#1f77b4", "o"),
    "lbs": ("LBS", "#7f7f7f", "s"),
    "fnopt": ("FNOpt", "#e377c2", "*"),
    "optimizer": ("gd / Adam / L-BFGS", "#17becf", "h"),
    "other": ("other", "#000000", "o"),
}
FRONT_COLOR = "#222222"
RING_COLOR = "#d62728"
FONT = 8
FAINT_ALPHA = 0.35


def num(s):
    try:
        return float(s)
    except (TypeError, ValueError):
        return math.nan


def count(s):
    v = num(s)
    return int(v) if math.isfinite(v) else 0


def family_key(r):
    fam = r["family"]
    if fam == "model":
        p = r.get("precision", "")
        return "learned-" + p if p in ("int8", "fp16", "fp32") else "learned-fp32"
    if fam == "fnopt":
        return "fnopt" if r["method"].lower().startswith("fnopt") else "optimizer:" + r["method"]
    return fam if fam in FAMILIES else "other"


def family_style(key):
    return FAMILIES["optimizer" if key.startswith("optimizer:") else key]


def short_label(key, r):
    """One short label for a family's best setting."""
    m = r["method"]
    if key.startswith("learned-"):
        return FAMILIES[key][0]
    if key == "xpbd-fast":
        base = m.split(" + ")[0].replace(" no-CCD", "")
        return "fast " + base.replace("XPBD-fast-", "XPBD-") + (" +" if " + " in m else "")
    if key == "xpbd":
        return m.split(" + ")[0] + (" +" if " + " in m else "")
    if key == "lbs":
        return "LBS" + (" +" if " + " in m else "")
    return m


def pareto(points):
    """Points (ms, err, row) with an error below every faster point's, sorted by ms."""
    front, best = [], math.inf
    for p in sorted(points, key=lambda p: (p[0], p[1])):
        if p[1] < best:
            front.append(p)
            best = p[1]
    return front


def fmt_val(v):
    return f"{v:.2g}" if v < 10 else f"{v:.0f}"


def nice_ceil(v):
    """The next round number at or above v (1, 1.2, 1.5, 2, 2.5, 3, ... times a power of ten)."""
    e = 10.0 ** math.floor(math.log10(v))
    for m in (1, 1.2, 1.5, 2, 2.5, 3, 3.5, 4, 4.5, 5, 6, 7, 8, 9, 10):
        if m * e >= v * 0.9999:
            return m * e
    return 10 * e


def fmt_ms(v, _pos=None):
    return f"{v:g}"


def overlap(a, b):
    w = min(a.x1, b.x1) - max(a.x0, b.x0)
    h = min(a.y1, b.y1) - max(a.y0, b.y0)
    return w * h if w > 0 and h > 0 else 0.0


def draw_panel(ax, sc, rows):
    """Draws one scenario; returns the labels still to place, as (ms, error, text, colour)."""
    mocap = sc in ("mocap", "cape")  # real motion: no ground truth, the share inside the body
    fn = not mocap and any(r["family"] == "fnopt" for r in rows)
    ekey = "e3d" if fn else "inside_body_pct" if mocap else "mve_cm"
    pts, unscored_nan, unscored_none = [], 0, 0
    for r in rows:
        ms, err = num(r["ms_per_frame"]), num(r[ekey])
        if count(r["nan_runs"]) > 0:
            unscored_nan += 1
        elif ms > 0 and math.isfinite(err):
            pts.append((ms, err, r))
        else:
            unscored_none += 1
    ax.set_title("cape on real motion (mocap test clips)" if sc == "cape" else
                 "real motion (mocap test clips)" if mocap else sc, fontsize=10, fontweight="bold")
    ax.set_xscale("log")
    ax.set_xlabel("ms per frame (log)", fontsize=FONT, loc="right")
    ax.set_ylabel("e3D vs XPBD reference (relative)" if fn else "cloth inside the body (%)" if mocap
                  else "mean vertex error (cm)", fontsize=FONT)
    ax.tick_params(labelsize=FONT)
    ax.grid(True, which="major", alpha=0.3)
    ax.grid(True, which="minor", axis="x", alpha=0.1)
    notes = []
    if unscored_nan:
        notes.append(f"{unscored_nan} NaN")
    if unscored_none:
        notes.append(f"{unscored_none} no {'e3D' if fn else 'inside_body' if mocap else 'MVE'}")
    if notes:
        # Under the tick labels on the left, level with the axis title (which sits on the right).
        ax.annotate("not scored: " + ", ".join(notes), (0, 0), xycoords="axes fraction", textcoords="offset points",
                    xytext=(0, -23), fontsize=FONT, ha="left", va="top", color="#666666", style="italic")
    if not pts:
        ax.text(0.5, 0.5, "no scored settings", transform=ax.transAxes, ha="center", fontsize=FONT)
        return []

    front = pareto(pts)
    on_front = {id(p[2]) for p in front}
    fams = {}
    for p in pts:
        fams.setdefault(family_key(p[2]), []).append(p)
    best = {}
    for key, fp in fams.items():
        cands = [p for p in fp if id(p[2]) in on_front] or fp
        best[key] = min(cands, key=lambda p: (p[1], p[0]))

    # Limits: the front and the labelled points, with a margin (log in x, linear in y from 0).
    keep = front + list(best.values())
    xs = [p[0] for p in keep]
    ys = [p[1] for p in keep]
    x0, x1 = min(xs) / 1.8, max(xs) * 2.6
    y1 = nice_ceil(max(ys) * 1.2) if max(ys) > 0 else 1.0
    ax.set_xlim(x0, x1)
    ax.set_ylim(0, y1)
    ax.xaxis.set_major_locator(LogLocator(base=10, subs=(1.0, 3.0) if x1 / x0 > 100 else (1.0, 2.0, 5.0)))
    ax.xaxis.set_major_formatter(FuncFormatter(fmt_ms))
    ax.xaxis.set_minor_formatter(NullFormatter())

    # Pareto front: min error for this many ms or less, carried to the right edge.
    fx = [p[0] for p in front] + [x1]
    fy = [p[1] for p in front] + [front[-1][1]]
    ax.step(fx, fy, where="post", color=FRONT_COLOR, linewidth=1.3, alpha=0.75, zorder=2)

    # Faint: every scored setting that is not its family's best. Off-scale ones go on the edge.
    offscale = []
    best_ids = {id(p[2]) for p in best.values()}
    for ms, err, r in pts:
        if id(r) in best_ids:
            continue
        color, marker = family_style(family_key(r))[1:]
        if x0 <= ms <= x1 and err <= y1:
            ax.plot(ms, err, marker=marker, color=color, markersize=4.5, alpha=FAINT_ALPHA, linestyle="none",
                    markeredgewidth=0, zorder=3)
        else:
            offscale.append((ms, err, color))
    # Off-scale: a triangle on the edge pointing outward; above-the-top ones are grouped by x with
    # one value label per group so the labels stay apart.
    tops = []
    for ms, err, color in offscale:
        if err > y1:
            cx = min(max(ms, x0 * 1.04), x1 / 1.04)
            ax.plot(cx, y1, marker="^", color=color, markersize=6, alpha=0.75, linestyle="none",
                    markeredgewidth=0, clip_on=False, zorder=4)
            tops.append((cx, err))
        else:
            right = ms > x1
            cx = x1 if right else x0
            ax.plot(cx, err, marker=">" if right else "<", color=color, markersize=6, alpha=0.75,
                    linestyle="none", markeredgewidth=0, clip_on=False, zorder=4)
            ax.annotate(f"{ms:.3g} ms".replace("e+0", "e"), (cx, err), textcoords="offset points",
                        xytext=(-4 if right else 4, 5), ha="right" if right else "left", va="bottom",
                        fontsize=FONT, color="#555555")
    # Group the top-edge values so their labels never touch: neighbours whose labels would overlap
    # (estimated width in pixels) merge into one range label.
    px = ax.figure.dpi / 72.0

    def text_of(errs):
        lo, hi = min(errs), max(errs)
        return fmt_val(hi) if fmt_val(lo) == fmt_val(hi) else f"{fmt_val(lo)}–{fmt_val(hi)}"

    def centre(g):
        dx = [ax.transData.transform((cx, y1))[0] for cx, _ in g]
        return (min(dx) + max(dx)) / 2

    groups = [[t] for t in sorted(tops)]
    merged = True
    while merged and len(groups) > 1:
        merged = False
        for i in range(len(groups) - 1):
            a, b = groups[i], groups[i + 1]
            wa = len(text_of([e for _, e in a])) * FONT * 0.62 * px
            wb = len(text_of([e for _, e in b])) * FONT * 0.62 * px
            if centre(b) - centre(a) < (wa + wb) / 2 + 4 * px:
                groups[i:i + 2] = [a + b]
                merged = True
                break
    for g in groups:
        gx = ax.transData.inverted().transform((centre(g), 0))[0]
        ax.annotate(text_of([e for _, e in g]), (gx, y1), textcoords="offset points", xytext=(0, -6),
                    ha="center", va="top", fontsize=FONT, color="#555555", zorder=5)

    # Best of each family: large filled marker, a red ring where some runs exploded, one label.
    labels = []
    order = ["lbs", "xpbd-fast", "xpbd", "learned-int8", "learned-fp16", "learned-fp32", "fnopt"]
    for key in sorted(best, key=lambda k: (order.index(k) if k in order else len(order), k)):
        ms, err, r = best[key]
        color, marker = family_style(key)[1:]
        size = 13 if marker == "*" else 9
        ax.plot(ms, err, marker=marker, color=color, markersize=size, linestyle="none",
                markeredgecolor="white", markeredgewidth=0.8, zorder=6)
        if count(r["exploded_runs"]) > 0 or count(r.get("garments_lost")) > 0:
            ax.plot(ms, err, marker="o", markerfacecolor="none", markeredgecolor=RING_COLOR, markersize=15,
                    markeredgewidth=1.3, linestyle="none", zorder=5.5)
        labels.append((ms, err, short_label(key, r), color))
    return labels


def place_labels(fig, ax, labels):
    """Greedy, deterministic placement: for each label try a ring of offsets around its point and keep
    the first that overlaps no placed label, no labelled marker and stays inside the axes."""
    if not labels:
        return
    renderer = fig.canvas.get_renderer()
    axbox = ax.get_window_extent(renderer)
    px = fig.dpi / 72.0
    markers = []
    for ms, err, _, _ in labels:
        cx, cy = ax.transData.transform((ms, err))
        r = 8 * px
        markers.append(Bbox([[cx - r, cy - r], [cx + r, cy + r]]))
    fixed = [t.get_window_extent(renderer) for t in ax.texts]
    cands = []
    for dist in (1.0, 1.8, 2.8):
        for dx, dy, ha, va in ((9, 4, "left", "bottom"), (9, -4, "left", "top"), (-9, 4, "right", "bottom"),
                               (-9, -4, "right", "top"), (0, 10, "center", "bottom"), (0, -10, "center", "top"),
                               (12, 0, "left", "center"), (-12, 0, "right", "center")):
            cands.append((dx * dist, dy * dist, ha, va))
    placed = []
    for ms, err, text, color in sorted(labels, key=lambda l: (l[1], l[0])):
        best = None
        for dx, dy, ha, va in cands:
            t = ax.annotate(text, (ms, err), textcoords="offset points", xytext=(dx, dy), ha=ha, va=va,
                            fontsize=FONT + 1, color="black", zorder=7,
                            bbox=dict(boxstyle="round,pad=0.15", fc="white", ec=color, lw=0.8, alpha=0.85),
                            arrowprops=dict(arrowstyle="-", color=color, lw=0.8, shrinkA=0, shrinkB=6))
            bb = t.get_window_extent(renderer).expanded(1.04, 1.1)
            score = sum(overlap(bb, o) for o in placed + markers + fixed)
            inside = (bb.x0 >= axbox.x0 and bb.x1 <= axbox.x1 and bb.y0 >= axbox.y0 and bb.y1 <= axbox.y1)
            if not inside:
                score += 1e6
            if best is None or score < best[0]:
                if best is not None:
                    best[1].remove()
                best = (score, t, bb)
            else:
                t.remove()
            if score == 0:
                break
        placed.append(best[2])


def legend_handles(present):
    """One line: family colours (the FNOpt panel labels each of its points), then marker meanings."""
    h, names = [], []
    for key in FAMILIES:
        if key in present and key not in ("fnopt", "optimizer"):
            name, color, marker = FAMILIES[key]
            h.append(Line2D([], [], marker=marker, color=color, linestyle="none", markersize=8,
                            markeredgecolor="white"))
            names.append(name)
    grey = "#555555"
    big = Line2D([], [], marker="o", color=grey, linestyle="none", markersize=8, markeredgecolor="white")
    faint = Line2D([], [], marker="o", color=grey, alpha=FAINT_ALPHA, linestyle="none", markersize=4.5,
                   markeredgewidth=0)
    h.append((big, faint))
    names.append("best / other settings")
    h.append(Line2D([], [], marker="^", color=grey, linestyle="none", markersize=6, markeredgewidth=0))
    names.append("off scale (value)")
    h.append(Line2D([], [], marker="o", markerfacecolor="none", markeredgecolor=RING_COLOR, linestyle="none",
                    markersize=11, markeredgewidth=1.3))
    names.append("some runs exploded / garment lost")
    h.append(Line2D([], [], color=FRONT_COLOR, linewidth=1.3))
    names.append("Pareto front")
    return h, names


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
    # the simulation scenarios first, then real motion, then the FNOpt grid (another metric)
    scenarios.sort(key=lambda sc: (sc == "fnopt-grid", sc in ("mocap", "cape"), sc == "cape"))
    n = len(scenarios)
    ncols = 1 if n == 1 else 2 if n in (2, 4) else 3
    nrows = math.ceil(n / ncols)
    width = 12 if ncols > 1 else 7
    height = 3.3 * nrows + 1.0
    fig, axes = plt.subplots(nrows, ncols, figsize=(width, height), squeeze=False)
    top_in, bottom_in = 0.85, 0.5
    fig.subplots_adjust(left=0.06 if ncols > 1 else 0.1, right=0.985, top=1 - top_in / height,
                        bottom=bottom_in / height, wspace=0.16, hspace=0.42)
    present, panels = set(), []
    for i, sc in enumerate(scenarios):
        ax = axes[i // ncols][i % ncols]
        srows = [r for r in rows if r["scenario"] == sc]
        for r in srows:
            k = family_key(r)
            present.add("optimizer" if k.startswith("optimizer:") else k)
        panels.append((ax, draw_panel(ax, sc, srows)))
    for j in range(n, nrows * ncols):
        axes[j // ncols][j % ncols].set_visible(False)
    fig.canvas.draw()
    for ax, labels in panels:
        place_labels(fig, ax, labels)
    fig.suptitle("weft: speed against accuracy per scenario — lower left is better", fontsize=11,
                 y=1 - 0.08 / height, va="top")
    handles, names = legend_handles(present)
    fig.legend(handles, names, loc="upper center", bbox_to_anchor=(0.5, 1 - 0.32 / height), ncol=len(handles),
               fontsize=FONT, frameon=False, handletextpad=0.4, columnspacing=1.3, handlelength=1.6,
               handler_map={tuple: HandlerTuple(ndivide=None, pad=0.6)})
    fig.savefig(args.out, dpi=110)


if __name__ == "__main__":
    main()
