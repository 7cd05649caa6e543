"""`weft ccd --queries FILE` (argv[1]: the weft binary): output format and results of the sample
queries, and clear failures on malformed input."""
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def main():
    weft = sys.argv[1]
    out = subprocess.run([weft, "ccd", "--queries", os.path.join(HERE, "queries_sample.txt")],
                         capture_output=True, text=True)
    failures = 0
    lines = out.stdout.split("\n")[:-1]
    expect = [(1, 0.5), (0, None), (1, 0.5), (0, None), (1, 0.5), (1, 0.0), (0, None)]
    if out.returncode != 0 or len(lines) != len(expect):
        print("unexpected output:", out.returncode, out.stdout, out.stderr)
        return 1
    for line, (hit, t) in zip(lines, expect):
        parts = line.split()
        if int(parts[0]) != hit:
            failures += 1
        elif hit:
            toi = float(parts[1])
            # conservative: at or slightly before the exact contact time
            failures += not (t - 1e-5 <= toi <= t)
        else:
            failures += len(parts) != 1
    failures += "queries" not in out.stderr
    bad = subprocess.run([weft, "ccd", "--queries", "-"], input="vf 1 2 3\n", capture_output=True, text=True)
    failures += bad.returncode == 0 or "24 numbers" not in bad.stderr
    bad = subprocess.run([weft, "ccd", "--queries", "-"], input="xx " + "0 " * 24 + "\n", capture_output=True, text=True)
    failures += bad.returncode == 0
    csv = subprocess.run([weft, "ccd", "--csv", os.path.join(HERE, "queries_sample_vf.csv"), "--type", "vf"],
                         capture_output=True, text=True)
    got = [line.split()[0] for line in csv.stdout.split("\n")[:-1]]
    failures += csv.returncode != 0 or got != ["1", "0", "1"]
    failures += "0 false negatives, 0 false positives; 1 queries not exactly representable" not in csv.stderr
    notype = subprocess.run([weft, "ccd", "--csv", os.path.join(HERE, "queries_sample_vf.csv")],
                            capture_output=True, text=True)
    failures += notype.returncode == 0
    missing = subprocess.run([weft, "ccd", "--queries", "/nonexistent/q.txt"], capture_output=True, text=True)
    failures += missing.returncode == 0
    print("weft ccd CLI: %d failures" % failures)
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
