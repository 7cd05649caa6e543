"""tools/train/pack.py and data.load_sequences on copies of the committed sample sequence:
--max-frames keeps the first N frames of cloth, pins and collider (decoded within half a grid
step), --split packs one split, --interleave spreads a smaller root evenly among a larger one, and a
name found both as a folder and in a pack is loaded once, from the folder.

  python3 tests/tools/train_pack.py SAMPLE_SEQ_DIR     (exit 77: numpy missing, skipped)
"""
import os
import shutil
import subprocess
import sys
import tempfile

try:
    import numpy as np
except ImportError:
    print("numpy missing: skipped")
    sys.exit(77)

HERE = os.path.dirname(os.path.abspath(__file__))
TRAIN = os.path.join(HERE, "..", "..", "tools", "train")
sys.path.insert(0, TRAIN)
import data as weft_data  # noqa: E402

FAILED = []


def check(cond, what):
    if not cond:
        FAILED.append(what)
        print("FAILED: " + what)


def copy_seq(src, root, name, split=None, pins_from=None):
    """The sample under root/name; with split, its meta.json says so; with pins_from, frames from
    pins_from on pin the first ten vertices."""
    dst = os.path.join(root, name)
    shutil.copytree(src, dst)
    if split is not None:
        import json
        with open(os.path.join(dst, "meta.json")) as f:
            meta = json.load(f)
        meta["split"] = split
        with open(os.path.join(dst, "meta.json"), "w") as f:
            json.dump(meta, f)
    if pins_from is not None:
        p = np.load(os.path.join(dst, "pinned.npy"))
        p[:] = 0
        p[pins_from:, :10] = 1
        np.save(os.path.join(dst, "pinned.npy"), p)
    return dst


def run_pack(*args):
    out = subprocess.run([sys.executable, os.path.join(TRAIN, "pack.py")] + list(args),
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, check=False)
    check(out.returncode == 0, f"pack.py {' '.join(args)} exited {out.returncode}: {out.stdout[-400:]}")
    return out.stdout


def packed_order(stdout):
    """The sequence names in the order pack.py wrote them ("[i/n] NAME split size")."""
    return [line.split()[1] for line in stdout.splitlines() if line.startswith("[")]


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: train_pack.py SAMPLE_SEQ_DIR")
    sample = sys.argv[1]
    full = weft_data.Sequence(sample)
    with tempfile.TemporaryDirectory(prefix="train_pack_") as tmp:
        # --max-frames: the first 9 frames of a sequence whose pins start at frame 3
        a = os.path.join(tmp, "a")
        os.makedirs(a)
        copy_seq(sample, a, "drop_1k_9000", split="train", pins_from=3)
        run_pack("--data", a, "--out", os.path.join(tmp, "cut"), "--max-frames", "9", "--check")
        cut = weft_data.load_sequences([os.path.join(tmp, "cut")])
        check(len(cut) == 1, f"one packed sequence, got {len(cut)}")
        if cut:
            p = cut[0]
            check(p.frames == 9 and p.pos.shape == (9,) + full.pos.shape[1:], f"9 frames kept, got {p.pos.shape}")
            check(np.abs(p.pos - full.pos[:9]).max() <= 1e-5 + 1e-7, "cloth within half the 20 um step")
            check(p.cpos is not None and p.cpos.shape[0] == 9, "the collider cut to 9 frames")
            check(p.pinned is not None and p.pinned.shape == (9, full.pos.shape[1])
                  and not p.pinned[:3].any() and p.pinned[3:, :10].all() and not p.pinned[3:, 10:].any(),
                  "the pins cut to 9 frames, as they were")
            check(p.meta["pack"].get("frames_kept") == [9, full.frames], f"meta says the cut: {p.meta['pack']}")
        check(weft_data.load_sequences([os.path.join(tmp, "none")]) == [], "a missing root holds no sequence")
        run_pack("--data", a, "--out", os.path.join(tmp, "whole"))
        w = weft_data.load_sequences([os.path.join(tmp, "whole")])
        check(len(w) == 1 and w[0].frames == full.frames, "without --max-frames every frame is packed")

        # a name in a folder and in a pack: loaded once, from the folder, whatever the root order
        for roots in ([a, os.path.join(tmp, "whole")], [os.path.join(tmp, "whole"), a]):
            seqs = weft_data.load_sequences(roots)
            check(len(seqs) == 1 and not seqs[0].__class__.__name__.startswith("Packed"),
                  f"roots {roots}: one sequence, from the folder, got {[type(s).__name__ for s in seqs]}")

        # --split and --interleave: root b holds three train sequences and one val, root a one train
        b = os.path.join(tmp, "b")
        os.makedirs(b)
        for i in range(3):
            copy_seq(sample, b, f"garment_1k_900{i}", split="train")
        copy_seq(sample, b, "garment_1k_9009", split="val")
        order = packed_order(run_pack("--data", b, a, "--split", "train", "--interleave",
                                      "--out", os.path.join(tmp, "mixed")))
        check(order == ["garment_1k_9000", "garment_1k_9001", "drop_1k_9000", "garment_1k_9002"],
              f"interleaved order: {order}")
        order = packed_order(run_pack("--data", b, a, "--split", "train", "--out", os.path.join(tmp, "plain")))
        check(order == ["garment_1k_9000", "garment_1k_9001", "garment_1k_9002", "drop_1k_9000"],
              f"root after root: {order}")
        order = packed_order(run_pack("--data", b, a, "--split", "val", "--out", os.path.join(tmp, "val")))
        check(order == ["garment_1k_9009"], f"--split val: {order}")
    if FAILED:
        sys.exit(f"{len(FAILED)} check(s) failed")
    print("train_pack: all checks passed")


if __name__ == "__main__":
    main()
