"""Held-out table: `weft eval` per method and split, MVE per scenario, as one markdown table.

  /usr/bin/python3 tools/bench/heldout_table.py --data data/refsim --split test val \
      --method game=model:tools/train/models/game.safetensors --method LBS=lbs --method XPBD-5=xpbd:5 \
      --out docs/data/heldout_test_val.md

Each --method is LABEL=METHOD[:ARG][,strain=PCT][,tether=CM][,scontact=CM][,push=CM][,recipe=worn] with METHOD one
of model:PATH (fp32), int8:PATH, fp16:PATH, lbs, xpbd:S, xpbd-fast:S; strain= and tether= add the runtime's strain
limit and tethers (`weft eval --strain-limit`, `--tether-cm`; scontact= the contact-aware limit's distance,
`--strain-contact-cm`; push= the collider push, `--push-cm`; recipe=worn the worn-garment recipe on worn garments,
`--recipe worn`), e.g. `game+SL10=model:game.safetensors,strain=10`;
a method chosen per scene is SCENARIO@METHOD alternatives joined by '|', '*' for every other
scenario, e.g. `'game_k16+drop=drop@model:drop.safetensors|*@model:game_k16.safetensors,strain=10'`
(each alternative runs on a temporary folder of links to that scenario's sequences);
every run is `weft eval --seq DATA --split SPLIT --ccd off|on` (240-frame rollouts
from the first two reference frames). The per-sequence lines eval prints are grouped by the
scenario in each sequence's name (drop_/garment_/gripper_) and averaged weighted by frames
(eval's own total weights by vertex-frames; the sequences' vertex counts differ by a few %). Also writes the per-sequence rows as CSV next to --out.

`--group garment` groups by garment kind instead (skirt, dress, T-shirt: meta.json's description,
"garment: KIND on ..."), for real-motion sets (`weft simgen --mocap`), and adds the garments eval
calls lost; `--jobs N` runs N evaluations at a time (each its own `weft eval` process).
"""
import concurrent.futures
import json
import argparse
import csv
import os
import re
import shlex
import subprocess
import sys
import tempfile

LINE = re.compile(r"^(\S+)\s+frames\s+(\d+)\s+MVE\s+([-\d.naninf]+) cm\s+coll\s+([-\d.]+)%\s+self\s+([-\d.]+)%\s+"
                  r"([-\d.]+) ms/frame(?:\s+\(p50 [^)]*\))?\s+strain\s+([-\d.naninf]+)\s+tokens\s+\S+(\s+NaN)?")
LOST = re.compile(r"\sgarment (kept|LOST)\b")
SCENARIOS = ("drop", "garment", "gripper")
KINDS = ("skirt", "dress", "tshirt")


def garment_kind(data, name):
    """The garment kind of a sequence (meta.json's description "garment: KIND on ..."), or None."""
    try:
        with open(os.path.join(data, name, "meta.json")) as f:
            m = re.match(r"garment: (\w+) on", json.load(f).get("description", ""))
    except (OSError, ValueError):
        return None
    return m.group(1) if m and m.group(1) in KINDS else None


OPTIONS = {"strain": "--strain-limit", "tether": "--tether-cm", "scontact": "--strain-contact-cm", "push": "--push-cm",
           "recipe": "--recipe"}


def method_args(spec):
    method, *options = spec.split(",")
    extra = []
    for opt in options:
        key, _, value = opt.partition("=")
        if key not in OPTIONS or not value:
            sys.exit(f"heldout_table: unknown option '{opt}' in '{spec}' "
                     "(strain=PCT, tether=CM, scontact=CM, push=CM, recipe=worn)")
        extra += [OPTIONS[key], value]
    kind, _, arg = method.partition(":")
    if kind in ("model", "int8", "fp16"):
        precision = {"model": "fp32"}.get(kind, kind)
        return ["--method", "model", "--model", arg, "--precision", precision] + extra
    if kind == "lbs":
        return ["--method", "lbs"] + extra
    if kind in ("xpbd", "xpbd-fast"):
        return ["--method", kind + ":" + arg] + extra
    sys.exit(f"heldout_table: unknown method '{spec}'")


def run(weft, data, split, spec, ccd, frames, pins="xpbd"):
    cmd = [weft, "eval", "--seq", data, "--split", split, "--ccd", ccd] + method_args(spec)
    if pins != "xpbd":
        cmd += ["--pins", pins]
    if frames:
        cmd += ["--frames", str(frames)]
    print("$ " + " ".join(cmd), file=sys.stderr, flush=True)
    out = subprocess.run(cmd, stdout=subprocess.PIPE, text=True, check=False)
    rows = []
    for line in out.stdout.splitlines():
        m = LINE.match(line.strip())
        if m:
            name = os.path.basename(m.group(1).rstrip("/"))
            lost = LOST.search(line)
            rows.append({"sequence": name, "scenario": name.split("_")[0], "kind": garment_kind(data, name),
                         "lost": bool(lost and lost.group(1) == "LOST"), "frames": int(m.group(2)),
                         "mve_cm": float(m.group(3)), "coll_pct": float(m.group(4)),
                         "self_pct": float(m.group(5)), "ms_per_frame": float(m.group(6)),
                         "max_strain": float(m.group(7)), "nan": bool(m.group(8))})
    # eval exits 1 when a rollout went NaN (a result: the table's NaN column); any other failure
    # (a sequence it could not load or step, no sequence at all) leaves no table
    if not rows or (out.returncode != 0 and not any(r["nan"] for r in rows)):
        sys.exit(f"heldout_table: `{' '.join(cmd)}` failed ({out.returncode}, {len(rows)} sequence lines)")
    return rows


def run_chosen(weft, data, split, spec, ccd, frames, pins):
    """A method chosen per scenario: 'drop@SPEC|*@SPEC'. Each alternative runs on a temporary
    folder of links to the sequences of its scenarios."""
    alts = [alt.partition("@") for alt in spec.split("|")]
    named = {sc for sc, _, _ in alts if sc != "*"}
    if any(not m for _, _, m in alts) or not named <= set(SCENARIOS):
        sys.exit(f"heldout_table: '{spec}': want SCENARIO@METHOD alternatives ({', '.join(SCENARIOS)} or *)")
    rows = []
    for sc, _, m in alts:
        wanted = {sc} if sc != "*" else set(SCENARIOS) - named
        with tempfile.TemporaryDirectory(prefix="heldout_") as tmp:
            n = 0
            for name in sorted(os.listdir(data)):
                if name.split("_")[0] in wanted and os.path.exists(os.path.join(data, name, "meta.json")):
                    os.symlink(os.path.abspath(os.path.join(data, name)), os.path.join(tmp, name))
                    n += 1
            if n:
                rows += run(weft, tmp, split, m, ccd, frames, pins)
    return rows


def mean(rows, key):
    w = sum(r["frames"] for r in rows)
    return sum(r[key] * r["frames"] for r in rows) / w if w else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weft", default="build/bin/weft")
    ap.add_argument("--data", required=True)
    ap.add_argument("--split", nargs="+", default=["test"])
    ap.add_argument("--method", action="append", required=True, help="LABEL=METHOD[:ARG]")
    ap.add_argument("--ccd", default="off", choices=["on", "off"])
    ap.add_argument("--pins", default="all", choices=["xpbd", "all"],
                    help="the sequences' pins (gripper grasps, waistbands) for XPBD only, or for every method")
    ap.add_argument("--frames", type=int, default=0, help="rollout length (default: the whole sequence)")
    ap.add_argument("--out", help="markdown file (default: print only)")
    ap.add_argument("--group", default="scenario", choices=["scenario", "garment"],
                    help="columns per scenario (drop, garment, gripper) or per garment kind (skirt, dress, tshirt)")
    ap.add_argument("--jobs", type=int, default=1, help="evaluations run at a time (default 1)")
    a = ap.parse_args()
    if a.jobs < 1:
        sys.exit("heldout_table: --jobs wants a count >= 1")
    by_kind = a.group == "garment"
    groups, key = (KINDS, "kind") if by_kind else (SCENARIOS, "scenario")

    runs = []
    for split in a.split:
        for m in a.method:
            label, _, spec = m.partition("=")
            if not spec:
                sys.exit(f"heldout_table: --method wants LABEL=METHOD, got '{m}'")
            runs.append((split, label, spec))

    def one(job):
        split, _, spec = job
        if "@" in spec:
            return run_chosen(a.weft, a.data, split, spec, a.ccd, a.frames, a.pins)
        return run(a.weft, a.data, split, spec, a.ccd, a.frames, a.pins)

    with concurrent.futures.ThreadPoolExecutor(max_workers=a.jobs) as pool:
        results = list(pool.map(one, runs))
    table, per_seq = [], []
    for (split, label, _), rows in zip(runs, results):
        for r in rows:
            per_seq.append(dict(r, split=split, method=label))
        cells = [split, label, f"{mean(rows, 'mve_cm'):.2f}"]
        for g in groups:
            sub = [r for r in rows if r[key] == g]
            cells.append(f"{mean(sub, 'mve_cm'):.2f} ({len(sub)})" if sub else "—")
        cells += [f"{mean(rows, 'coll_pct'):.2f}", f"{mean(rows, 'self_pct'):.2f}",
                  f"{mean(rows, 'ms_per_frame'):.2f}", f"{max((r['max_strain'] for r in rows), default=0):.1f}",
                  "yes" if any(r["nan"] for r in rows) else "no"]
        if by_kind:
            cells.append(f"{sum(r['lost'] for r in rows)} of {len(rows)}")
        table.append(cells)

    cols = " | ".join(f"{g} (n)" for g in groups)
    head = (f"| split | method | all | {cols} | collision % | self-collision % | ms/frame | max strain | NaN |"
            + (" lost (eval's rule) |" if by_kind else "") + "\n|---|---|---:|" + "---:|" * len(groups)
            + "---:|---:|---:|---:|---|" + ("---:|" if by_kind else "") + "\n")
    md = head + "".join("| " + " | ".join(c) + " |\n" for c in table)
    print(md)
    if a.out:
        cmd = "/usr/bin/python3 tools/bench/heldout_table.py " + " ".join(
            [f"--data {a.data}", "--split " + " ".join(a.split), f"--ccd {a.ccd}", f"--pins {a.pins}"] +
            ([f"--group {a.group}"] if by_kind else []) +
            [f"--method {shlex.quote(m)}" for m in a.method] + ([f"--frames {a.frames}"] if a.frames else []) +
            [f"--out {a.out}"])
        with open(a.out, "w") as f:
            f.write(f"MVE in cm, 240-frame rollouts, CCD {a.ccd}, pins for {'every method' if a.pins == 'all' else 'XPBD only'}; made by\n\n```\n{cmd}\n```\n\n" + md)
        with open(os.path.splitext(a.out)[0] + ".csv", "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=["split", "method", "sequence", "scenario", "kind", "frames", "mve_cm",
                                              "coll_pct", "self_pct", "ms_per_frame", "max_strain", "nan", "lost"])
            w.writeheader()
            w.writerows(per_seq)


if __name__ == "__main__":
    main()
