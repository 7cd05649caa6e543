"""The xpbd prior's ctypes entry (tools/train/weft_sim.py) against the weft tool.

argv[1]: the shared library, argv[2]: the weft tool, argv[3]: a sequence folder (the sample
drop). The first frame `weft eval --method xpbd:S --write-pos` writes is one XPBD frame at S
substeps from the reference frames (1, 0) with the collider at 1 and 2, exactly what
XpbdPrior(substeps=S).step(x1, x0, c1, c2) computes: the same solver, so the two must agree bit
for bit. That holds the binding's garment_def layout (method, meshes, substeps, CCD off) to the
header's. A NaN state is refused with the library's message."""
import os
import subprocess
import sys
import tempfile

import numpy as np

os.environ["WEFT_LIB"] = sys.argv[1]
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tools", "train"))
import weft_sim  # noqa: E402


def main():
    lib, tool, seq = sys.argv[1:4]
    x = np.load(os.path.join(seq, "cloth_pos.npy"))
    c = np.load(os.path.join(seq, "collider_pos.npy"))
    rest = np.load(os.path.join(seq, "rest_pos.npy"))
    faces = np.load(os.path.join(seq, "faces.npy"))
    cfaces = np.load(os.path.join(seq, "collider_faces.npy"))
    failures = 0
    first = {}
    with tempfile.TemporaryDirectory() as tmp:
        for S in (1, 2):
            out = os.path.join(tmp, str(S))
            r = subprocess.run([tool, "eval", "--seq", seq, "--method", f"xpbd:{S}", "--ccd", "off", "--frames", "3",
                                "--write-pos", out], capture_output=True, text=True)
            if r.returncode != 0:
                print(f"weft eval xpbd:{S} failed: {r.stderr}")
                return 1
            track = np.load(os.path.join(out, os.path.basename(os.path.normpath(seq)) + ".npy"))
            sim = weft_sim.XpbdPrior(rest, faces, c[0], cfaces, S)
            y = sim.step(x[1], x[0], c[1], c[2])
            first[S] = y
            err = float(np.abs(y - track[2]).max())
            moved = float(np.abs(y - x[1]).max())
            print(f"substeps {S}: prior vs weft eval's first frame max |diff| {err:.3g} m (moves {moved:.3g} m)")
            failures += not (err == 0.0 and moved > 1e-4)
            # restarted anywhere: the same state gives the same frame again
            sim.step(x[5], x[4], c[5], c[6])
            failures += not np.array_equal(sim.step(x[1], x[0], c[1], c[2]), y)
            bad = x[1].copy()
            bad[3, 1] = np.nan
            try:
                sim.step(bad, x[0], c[1], c[2])
                print("a NaN state was accepted")
                failures += 1
            except RuntimeError as e:
                failures += "NaN" not in str(e)
            sim.close()
    failures += np.array_equal(first[1], first[2])   # the substeps reach the solver
    print("FAIL" if failures else "ok")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
