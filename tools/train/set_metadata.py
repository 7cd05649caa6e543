#!/usr/bin/env python3
"""Sets one __metadata__ key of a safetensors file in place, tensors untouched.

    /usr/bin/python3 tools/train/set_metadata.py FILE KEY VALUE

The header is rewritten (JSON, padded with spaces to a multiple of 8 bytes) and the data section
copied unchanged: tensor offsets are relative to it. Used to record a model's deployed settings,
e.g. KEY deploy, VALUE '{"strain_limit": 0.1, "tether_distance": 0.08, "push": 0.005, "ccd": false}'
(docs/MODEL_FORMAT.md, *Deployed settings*); `weft quantize` carries such keys into its outputs.
"""
import json
import os
import struct
import sys


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    path, key, value = sys.argv[1:]
    with open(path, "rb") as f:
        n = struct.unpack("<Q", f.read(8))[0]
        if n > 100 << 20:
            sys.exit(f"{path}: header of {n} bytes is not a safetensors header")
        header = json.loads(f.read(n))
        data = f.read()
    meta = header.setdefault("__metadata__", {})
    meta[key] = value
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 8)
    tmp = path + ".tmp"
    with open(tmp, "wb") as f:
        f.write(struct.pack("<Q", len(text)))
        f.write(text)
        f.write(data)
    os.replace(tmp, path)
    print(f"{path}: metadata {key} = {value}")


if __name__ == "__main__":
    main()
