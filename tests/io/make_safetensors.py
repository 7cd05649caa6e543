#!/usr/bin/python3
"""Independent safetensors implementation (numpy only) used to cross-check weft's reader and
writer against the format description rather than against weft's own code.

    make_safetensors.py write PATH   writes the reference file test_crosscheck.c reads
    make_safetensors.py check PATH   verifies a file weft wrote with the same contents

Both sides compute tensor values from the formulas in `reference_tensors`, mirrored in
tests/io/test_crosscheck.c.
"""
import json
import struct
import sys

import numpy as np

CONFIG = {"latent_count": 16, "ratio": 0.5, "tag": "x", "dims": [1, 2, 3], "flag": True}
METADATA = {"name": "py-crosscheck", "architecture": "none", "config": json.dumps(CONFIG)}


def bf16_bits(values):
    """Round-to-nearest-even float32 -> bfloat16 bit patterns (numpy has no bfloat16)."""
    bits = np.asarray(values, dtype=np.float32).view(np.uint32).astype(np.uint64)
    rounded = (bits + 0x7FFF + ((bits >> 16) & 1)) >> 16
    return rounded.astype(np.uint16)


def reference_tensors():
    """name -> (safetensors dtype, shape, little-endian bytes)."""
    out = {}
    f32 = (np.arange(15, dtype=np.float32) * 0.25 - 1.0).reshape(3, 5)
    out["w.f32"] = ("F32", [3, 5], f32.astype("<f4").tobytes())
    f16 = ((np.arange(8, dtype=np.float32) - 3.0) * 0.5).reshape(4, 2)
    out["w.f16"] = ("F16", [4, 2], f16.astype("<f2").tobytes())
    bf = np.arange(7, dtype=np.float32) * 2.0 - 5.0
    out["w.bf16"] = ("BF16", [7], bf16_bits(bf).astype("<u2").tobytes())
    i8 = (np.arange(12) - 6).astype(np.int8).reshape(2, 3, 2)
    out["q.i8"] = ("I8", [2, 3, 2], i8.tobytes())
    i32 = np.arange(5, dtype=np.int64) * 100000 - 7
    out["idx.i32"] = ("I32", [5], i32.astype("<i4").tobytes())
    u8 = (np.arange(9) * 29 % 256).astype(np.uint8)
    out["mask.u8"] = ("U8", [9], u8.tobytes())
    out["scalar"] = ("F32", [], np.array(3.5, dtype="<f4").tobytes())
    out["empty"] = ("F32", [0, 4], b"")
    return out


ITEMSIZE = {"F32": 4, "I32": 4, "F16": 2, "BF16": 2, "I8": 1, "U8": 1}


def write(path):
    tensors = reference_tensors()
    # Layout as the format's reference writer does it: descending alignment, then name.
    order = sorted(tensors, key=lambda n: (-ITEMSIZE[tensors[n][0]], n))
    header = {"__metadata__": METADATA}
    data = bytearray()
    for name in order:
        dtype, shape, raw = tensors[name]
        header[name] = {"dtype": dtype, "shape": shape, "data_offsets": [len(data), len(data) + len(raw)]}
        data += raw
    text = json.dumps(header, separators=(",", ":")).encode("utf-8")
    text += b" " * (-(8 + len(text)) % 8)
    with open(path, "wb") as f:
        f.write(struct.pack("<Q", len(text)))
        f.write(text)
        f.write(data)


def check(path):
    with open(path, "rb") as f:
        blob = f.read()
    (n,) = struct.unpack_from("<Q", blob, 0)
    assert 8 + n <= len(blob), "header length beyond file"
    assert (8 + n) % 8 == 0, "data section not 8-aligned"
    header = json.loads(blob[8 : 8 + n].decode("utf-8"))
    data = blob[8 + n :]
    meta = header.pop("__metadata__")
    assert meta["name"] == METADATA["name"], meta
    assert meta["architecture"] == METADATA["architecture"], meta
    assert json.loads(meta["config"]) == CONFIG, meta["config"]
    expected = reference_tensors()
    assert set(header) == set(expected), sorted(header)
    end = 0
    for name, entry in sorted(header.items(), key=lambda kv: kv[1]["data_offsets"]):
        dtype, shape, raw = expected[name]
        begin, stop = entry["data_offsets"]
        assert begin == end, f"{name}: not contiguous ({begin} != {end})"
        assert begin % ITEMSIZE[dtype] == 0, f"{name}: misaligned"
        assert entry["dtype"] == dtype and entry["shape"] == shape, (name, entry)
        assert data[begin:stop] == raw, f"{name}: bytes differ"
        end = stop
    assert end == len(data), "trailing bytes"
    print(f"{path}: {len(header)} tensors verified")


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] not in ("write", "check"):
        sys.exit("usage: make_safetensors.py write|check PATH")
    (write if sys.argv[1] == "write" else check)(sys.argv[2])
