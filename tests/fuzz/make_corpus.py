#!/usr/bin/python3
"""Regenerates the seed corpus in tests/fuzz/corpus/safetensors/ (small valid and broken
safetensors files). Run: /usr/bin/python3 tests/fuzz/make_corpus.py"""
import json
import os
import struct
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "io"))
import make_safetensors  # noqa: E402

OUT = os.path.join(HERE, "corpus", "safetensors")


def image(header, data=b"", pad=True):
    text = header if isinstance(header, bytes) else json.dumps(header, separators=(",", ":")).encode()
    if pad:
        text += b" " * (-(8 + len(text)) % 8)
    return struct.pack("<Q", len(text)) + text + data


def pack(tensors, metadata=None):
    """tensors: list of (name, dtype, shape, raw bytes), laid out in the given order."""
    header = {"__metadata__": metadata} if metadata else {}
    data = b""
    for name, dtype, shape, raw in tensors:
        header[name] = {"dtype": dtype, "shape": shape, "data_offsets": [len(data), len(data) + len(raw)]}
        data += raw
    return image(header, data)


def main():
    os.makedirs(OUT, exist_ok=True)
    files = {}
    tmp = os.path.join(OUT, "valid_all_dtypes.safetensors")
    make_safetensors.write(tmp)
    q8 = (np.arange(32) % 255 - 127).astype(np.int8).tobytes()
    scale = np.array([0.5, 0.25, 1.0, 0.0], dtype="<f4").tobytes()
    bias = np.array([1.0, -1.0, 0.5, 2.0], dtype="<f4").tobytes()
    files["valid_quantized.safetensors"] = pack(
        [("lin.w.scale", "F32", [4], scale), ("lin.b", "F32", [4], bias), ("lin.w.q8", "I8", [4, 8], q8)],
        {"name": "q", "config": json.dumps({"width": 8, "act": "gelu", "modes": [1, 2], "skip": False})},
    )
    files["valid_empty.safetensors"] = image(b"{}")
    files["valid_scalar_and_empty.safetensors"] = pack(
        [("s", "F32", [], struct.pack("<f", 1.5)), ("e", "F16", [0, 3], b""), ("u", "U8", [3], b"\x01\x02\x03")]
    )
    files["valid_unpadded.safetensors"] = image({"a": {"dtype": "I32", "shape": [1], "data_offsets": [0, 4]}},
                                                b"\x07\x00\x00\x00", pad=False)
    files["bad_overlap.safetensors"] = image(
        {"a": {"dtype": "F32", "shape": [2], "data_offsets": [0, 8]},
         "b": {"dtype": "F32", "shape": [2], "data_offsets": [4, 12]}}, bytes(12))
    files["bad_duplicate.safetensors"] = image(
        b'{"a":{"dtype":"U8","shape":[1],"data_offsets":[0,1]},"a":{"dtype":"U8","shape":[1],"data_offsets":[1,2]}}',
        b"\x00\x00")
    files["bad_dtype.safetensors"] = image({"a": {"dtype": "F64", "shape": [1], "data_offsets": [0, 8]}}, bytes(8))
    files["bad_overflow.safetensors"] = image(
        {"a": {"dtype": "F32", "shape": [1099511627776, 1099511627776], "data_offsets": [0, 4]}}, bytes(4))
    files["bad_truncated.safetensors"] = pack([("a", "F32", [4], bytes(16))])[:-5]
    files["bad_metadata.safetensors"] = image({"__metadata__": {"config": 3}})
    files["bad_config.safetensors"] = pack([("a", "U8", [1], b"\x00")],
                                           {"architecture": "clothtransformer", "config": "{\"d\": [[1]]}"})
    files["bad_header_length.safetensors"] = struct.pack("<Q", 1 << 40) + b"{}"
    for name, blob in files.items():
        with open(os.path.join(OUT, name), "wb") as f:
            f.write(blob)
    print(f"{len(files) + 1} files in {OUT}")


if __name__ == "__main__":
    main()
