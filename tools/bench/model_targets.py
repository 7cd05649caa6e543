"""The worn-garment model's targets, measured in one run (docs/MODEL.md, *Targets*).

  /usr/bin/python3 tools/bench/model_targets.py --mocap data/evalset --procedural data/proc_test \
      --out docs/data/model_targets.md

The shipped worn-garment model in int8 and fp32, LBS and the fast XPBD-10, every one as a game wears
it (`weft eval --recipe worn`, the recipe of WEAR.md for the garment's kind and the method), roll
out the test sequences of two sets with the sequences' pins and CCD off: the real-motion windows of
the mocap library's test clips (`weft simgen --mocap test`) and the procedural test garments
(`weft simgen --all --only garment --tier 1k --split test`); then the learned model alone runs the
2,400-frame playlist of every test clip (`weft bench mocap --chain 2400 --methods model`) for the
garments lost and non-finite states over a long rollout. Each target is printed with its measured
value, its limit and whether it is met.

Targets: the int8 model's MVE at most the fast XPBD-10's and at most 0.7 x LBS's on each set; its
ms a frame at most a tenth of the fast XPBD-10's (the same run, one evaluation at a time); int8 at
most 1.05 x fp32's MVE; no garment lost (eval's rule over the 240-frame rollouts; the stability
suite's over the playlist) and no NaN.

A measurement that fails (an evaluation or the playlist) fails the run and writes nothing: unmet
targets are a result (exit status 0), a missing figure is not. Timings need the machine otherwise
idle: run nothing beside it.
"""
import argparse
import csv
import os
import shlex
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import heldout_table  # noqa: E402


mean = heldout_table.mean  # frame-weighted, as the held-out tables


def measure_set(weft, data, model, frames):
    """{label: rows} for the four methods on the test split of DATA, as worn."""
    methods = {
        "int8": f"int8:{model}.int8.safetensors,recipe=worn",
        "fp32": f"model:{model}.safetensors,recipe=worn",
        "LBS": "lbs,recipe=worn",
        "fast XPBD-10": "xpbd-fast:10,recipe=worn",
    }
    out = {}
    for label, spec in methods.items():
        out[label] = heldout_table.run(weft, data, "test", spec, "off", frames, pins="all")
    return out


def playlist(weft, model, frames):
    """(cells, lost) of the learned int8 model over the playlist of every test clip; a step that
    fails (a non-finite state among them) fails the bench, and so this run."""
    with tempfile.TemporaryDirectory(prefix="targets_") as tmp:
        path = os.path.join(tmp, "chain.csv")
        cmd = [weft, "bench", "mocap", "--split", "test", "--frames", str(frames), "--chain", str(frames),
               "--methods", "model", "--model", f"{model}.int8.safetensors", "--retime", "0", "--csv", path]
        print("$ " + " ".join(cmd), file=sys.stderr, flush=True)
        done = subprocess.run(cmd, stdout=subprocess.DEVNULL, check=False)
        if done.returncode != 0 or not os.path.exists(path):
            sys.exit(f"model_targets: `{' '.join(cmd)}` failed ({done.returncode})")
        with open(path, newline="") as f:
            rows = list(csv.DictReader(f))
    if not rows:
        sys.exit("model_targets: the playlist wrote no cell")
    return len(rows), sum(int(r["lost"]) for r in rows)


def targets(sets, chain, chain_frames):
    """The rows of the targets table: (target, measured, limit, met)."""
    out = []
    for name, res in sets.items():
        i8, f32, lbs, xp = (mean(res[k], "mve_cm") for k in ("int8", "fp32", "LBS", "fast XPBD-10"))
        ms_i8, ms_xp = mean(res["int8"], "ms_per_frame"), mean(res["fast XPBD-10"], "ms_per_frame")
        n = len(res["int8"])
        lost = sum(r["lost"] for r in res["int8"])
        nan = sum(r["nan"] for r in res["int8"])
        out += [
            (f"{name}: MVE int8 <= fast XPBD-10 (cm)", f"{i8:.2f}", f"{xp:.2f}", i8 <= xp),
            (f"{name}: MVE int8 <= 0.7 x LBS (cm)", f"{i8:.2f}", f"{0.7 * lbs:.2f} (LBS {lbs:.2f})", i8 <= 0.7 * lbs),
            (f"{name}: ms a frame int8 <= fast XPBD-10 / 10", f"{ms_i8:.2f} (1/{ms_xp / ms_i8:.1f})",
             f"{ms_xp / 10:.2f}", ms_i8 <= ms_xp / 10),
            (f"{name}: MVE int8 <= 1.05 x fp32 (cm)", f"{i8:.2f}", f"{1.05 * f32:.2f} (fp32 {f32:.2f})",
             i8 <= 1.05 * f32),
            (f"{name}: garments lost, 240-frame rollouts (eval's rule)", f"{lost} of {n}", "0", lost == 0),
            (f"{name}: rollouts with NaN", f"{nan} of {n}", "0", nan == 0),
        ]
    cells, lost = chain
    out.append((f"{chain_frames:,}-frame playlist: garments lost (stability suite's rule), no NaN", f"{lost} of {cells}", "0",
                lost == 0))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--weft", default="build/bin/weft")
    ap.add_argument("--mocap", required=True, help="real-motion windows (weft simgen --mocap test)")
    ap.add_argument("--procedural", required=True, help="procedural garments with a test split")
    ap.add_argument("--model", default="tools/train/models/garment",
                    help="the model's files without their suffix: MODEL.safetensors and MODEL.int8.safetensors")
    ap.add_argument("--frames", type=int, default=238, help="scored frames of each rollout (default 238)")
    ap.add_argument("--chain", type=int, default=2400, help="playlist frames (default 2400)")
    ap.add_argument("--out", help="markdown file (default: print only)")
    a = ap.parse_args()
    for suffix in (".safetensors", ".int8.safetensors"):
        if not os.path.isfile(a.model + suffix):
            sys.exit(f"model_targets: no model file {a.model + suffix}")
    if a.frames < 1 or a.chain < 1:
        sys.exit("model_targets: --frames and --chain want counts >= 1")

    t0 = time.time()
    sets = {"real motion": measure_set(a.weft, a.mocap, a.model, a.frames),
            "procedural": measure_set(a.weft, a.procedural, a.model, a.frames)}
    chain = playlist(a.weft, a.model, a.chain)
    rows = targets(sets, chain, a.chain)

    md = ["| set | method | sequences | MVE (cm) | skirt / dress / T-shirt (cm) | ms/frame | lost | NaN |",
          "|---|---|---:|---:|---|---:|---:|---:|"]
    for name, res in sets.items():
        for label, rs in res.items():
            kinds = " / ".join(f"{mean(sub, 'mve_cm'):.2f}" if sub else "—"
                               for sub in ([r for r in rs if r["kind"] == k] for k in heldout_table.KINDS))
            md.append(f"| {name} | {label} | {len(rs)} | {mean(rs, 'mve_cm'):.2f} | {kinds} | "
                      f"{mean(rs, 'ms_per_frame'):.2f} | {sum(r['lost'] for r in rs)} | {sum(r['nan'] for r in rs)} |")
    md += ["", "| target | measured | limit | met |", "|---|---:|---:|---|"]
    md += [f"| {t} | {m} | {lim} | {'yes' if ok else '**no**'} |" for t, m, lim, ok in rows]
    text = "\n".join(md) + "\n"
    print(text)
    met = sum(ok for *_, ok in rows)
    print(f"model_targets: {met} of {len(rows)} targets met, {time.time() - t0:.0f} s", file=sys.stderr)
    if a.out:
        cmd = " ".join(["/usr/bin/python3 tools/bench/model_targets.py", f"--mocap {shlex.quote(a.mocap)}",
                        f"--procedural {shlex.quote(a.procedural)}"] +
                       ([f"--model {shlex.quote(a.model)}"] if a.model != "tools/train/models/garment" else []) +
                       ([f"--frames {a.frames}"] if a.frames != 238 else []) +
                       ([f"--chain {a.chain}"] if a.chain != 2400 else []) + [f"--out {a.out}"])
        with open(a.out, "w") as f:
            f.write("The worn-garment model's targets (MODEL.md, *Targets*): every method as worn (`weft eval "
                    "--recipe worn`), 240-frame rollouts from the first two reference frames, CCD off, the "
                    f"sequences' pins, one evaluation at a time; the playlist by `weft bench mocap --chain`. "
                    f"Made in {time.time() - t0:.0f} s by\n\n```\n{cmd}\n```\n\n" + text)


if __name__ == "__main__":
    main()
