"""tools/bench/model_targets.py on copies of the committed sample sequence (a test split of one):
the table carries every method of both sets and every target row; a missing model file and an
evaluation that fails end the run with no table written.

  /usr/bin/python3 tests/tools/model_targets.py WEFT SAMPLE_SEQ_DIR
"""
import json
import os
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..", "..")
SCRIPT = os.path.join(ROOT, "tools", "bench", "model_targets.py")
MODEL = os.path.join(ROOT, "tools", "train", "models", "garment")

FAILED = []


def check(cond, what):
    if not cond:
        FAILED.append(what)
        print("FAILED: " + what)


def test_set(src, root):
    dst = os.path.join(root, "garment_sample")
    shutil.copytree(src, dst)
    with open(os.path.join(dst, "meta.json")) as f:
        meta = json.load(f)
    meta["split"] = "test"
    with open(os.path.join(dst, "meta.json"), "w") as f:
        json.dump(meta, f)
    return root


def run(weft, *args):
    out = subprocess.run([sys.executable, SCRIPT, "--weft", weft] + list(args), stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True, check=False, cwd=ROOT)
    return out.returncode, out.stdout


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: model_targets.py WEFT SAMPLE_SEQ_DIR")
    weft, sample = os.path.abspath(sys.argv[1]), sys.argv[2]
    with tempfile.TemporaryDirectory(prefix="targets_test_") as tmp:
        a = test_set(sample, os.path.join(tmp, "a"))
        b = test_set(sample, os.path.join(tmp, "b"))
        md = os.path.join(tmp, "t.md")
        rc, out = run(weft, "--mocap", a, "--procedural", b, "--frames", "20", "--chain", "8", "--out", md)
        check(rc == 0, f"a run on the sample exited {rc}: {out[-600:]}")
        text = open(md).read() if os.path.exists(md) else ""
        for s in ("real motion", "procedural"):
            for m in ("int8", "fp32", "LBS", "fast XPBD-10"):
                check(f"| {s} | {m} | 1 |" in text, f"the table has no row for {s} / {m}")
        targets = [ln for ln in text.splitlines() if ln.startswith("| ") and ln.rstrip().endswith(("| yes |", "| **no** |"))]
        check(len(targets) == 13, f"13 target rows, got {len(targets)}")
        check("model_targets.py --mocap" in text, "the file names its command")

        md2 = os.path.join(tmp, "t2.md")
        rc, out = run(weft, "--mocap", a, "--procedural", b, "--model", os.path.join(tmp, "nothing"), "--out", md2)
        check(rc != 0 and "no model file" in out and not os.path.exists(md2),
              f"a missing model: exit {rc}, file {os.path.exists(md2)}: {out[-300:]}")

        empty = os.path.join(tmp, "empty")
        os.makedirs(empty)
        rc, out = run(weft, "--mocap", a, "--procedural", empty, "--frames", "20", "--chain", "8", "--out", md2)
        check(rc != 0 and "failed" in out and not os.path.exists(md2),
              f"a set with no sequence: exit {rc}, file {os.path.exists(md2)}: {out[-300:]}")
    if FAILED:
        sys.exit(f"{len(FAILED)} checks failed")
    print("model_targets: ok")


if __name__ == "__main__":
    if not os.path.isfile(MODEL + ".int8.safetensors"):
        print("no shipped garment model: skipped")
        sys.exit(77)
    main()
