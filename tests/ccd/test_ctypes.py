"""The ctypes entry (tools/train/weft_ccd.py) against the shared library given as argv[1]."""
import os
import sys

import numpy as np

os.environ["WEFT_LIB"] = sys.argv[1]
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tools", "train"))
import weft_ccd  # noqa: E402


def grid(n, y, dx=0.0):
    xs, zs = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    pos = np.stack([xs.ravel() + dx, np.full(n * n, y), zs.ravel()], axis=1)
    tris = []
    for i in range(n - 1):
        for j in range(n - 1):
            a = i * n + j
            tris += [(a, a + n, a + 1), (a + 1, a + n, a + n + 1)]
    return pos, np.array(tris, dtype=np.uint32)


def main():
    failures = 0
    # Single queries: a vertex falling through a static triangle at t = 0.5.
    q = np.array([[0.2, 0.2, 1], [0, 0, 0], [1, 0, 0], [0, 1, 0],
                  [0.2, 0.2, -1], [0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float64)
    hit, toi = weft_ccd.vertex_face(q)
    failures += not (hit and 0.49 < toi <= 0.5)
    hit, _ = weft_ccd.vertex_face(q + np.array([5.0, 0, 0]) * (np.arange(8)[:, None] == 0))
    failures += hit
    e = np.array([[-1, 0.5, 1], [1, 0.5, 1], [0.5, -1, 0], [0.5, 1, 0],
                  [-1, 0.5, -1], [1, 0.5, -1], [0.5, -1, 0], [0.5, 1, 0]], dtype=np.float64)
    hit, toi = weft_ccd.edge_edge(e)
    failures += not (hit and 0.49 < toi <= 0.5)

    # Two layers of one mesh passing through each other.
    a, ta = grid(8, 0.1)
    b, tb = grid(8, -0.1, 0.03)
    x0 = np.concatenate([a, b])
    tris = np.concatenate([ta, tb + len(a)])
    x1 = x0.copy()
    x1[: len(a), 1] -= 0.2
    x1[len(a):, 1] += 0.2
    world = weft_ccd.CCDWorld(tris, len(x0))
    hits = world.detect(x0, x1, types="self")
    k = len(hits["toi"])
    failures += not (k > 0 and hits["total"] == k)
    failures += not np.all((hits["toi"] >= 0) & (hits["toi"] <= 1))
    failures += not np.all((hits["vertices"] >= 0) & (hits["vertices"] < len(x0)))
    failures += not set(hits["type"].tolist()) <= {3, 4}
    # The layers meet at t = 0.5 (half the gap each way).
    failures += not abs(hits["toi"].min() - 0.5) < 0.01
    xs = weft_ccd.safe_positions(x0, x1, hits["vertices"], hits["toi"])
    failures += xs.shape != (k, 4, 3)
    loss = np.mean(np.sum((x1[hits["vertices"]] - xs) ** 2, axis=2).mean(axis=1))
    failures += not loss > 0
    fixed, stats = world.postprocess(x0, x1)
    after = world.detect(x0, fixed, types="self")
    failures += after["total"] != 0
    failures += stats["iterations"] < 2
    try:
        world.detect(x0, x1[:-1], types="self")
        failures += 1
    except ValueError:
        pass
    x1[0, 0] = np.nan
    try:
        world.detect(x0, x1, types="self")
        failures += 1
    except RuntimeError as err:
        failures += "NaN" not in str(err)
    world.close()
    print("ctypes CCD: %d self hits, loss %.4g, post-process %s, %d failures" % (k, loss, stats, failures))
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
