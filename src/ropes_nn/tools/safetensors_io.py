#!/usr/bin/python3
"""A reader and writer for .safetensors that follows the published format with numpy only
(Debian has no python3-safetensors): 8-byte little-endian header length, JSON header,
raw little-endian tensor bytes. Used by ropes_nn's tests and fixture scripts.

    safetensors_io.py summary FILE        print name, dtype, shape and float64 sum per tensor
    safetensors_io.py export FILE DIR     write each tensor as DIR/<name>.npy (numpy.save);
                                          with python3-torch installed, each goes through
                                          torch.from_numpy(...).numpy() on the way
"""
import json
import struct
import sys

import numpy as np

DTYPES = {"U8": np.uint8, "I32": np.int32, "I64": np.int64, "F32": np.float32, "F64": np.float64}
CODES = {np.dtype(v): k for k, v in DTYPES.items()}


def load(path):
    """Returns (dict name -> numpy array, metadata dict)."""
    with open(path, "rb") as f:
        blob = f.read()
    (n,) = struct.unpack("<Q", blob[:8])
    header = json.loads(blob[8:8 + n])
    data = blob[8 + n:]
    metadata = header.pop("__metadata__", {})
    tensors = {}
    for name, entry in header.items():
        begin, end = entry["data_offsets"]
        dtype = np.dtype(DTYPES[entry["dtype"]]).newbyteorder("<")
        tensors[name] = np.frombuffer(data[begin:end], dtype=dtype).reshape(entry["shape"]).copy()
    return tensors, metadata


def save(path, tensors, metadata=None):
    """Writes numpy arrays (dict, in its order) with optional string metadata."""
    header, chunks, offset = {}, [], 0
    if metadata:
        header["__metadata__"] = {str(k): str(v) for k, v in metadata.items()}
    for name, array in tensors.items():
        a = np.ascontiguousarray(array)
        raw = a.astype(a.dtype.newbyteorder("<"), copy=False).tobytes()
        header[name] = {"dtype": CODES[a.dtype], "shape": list(a.shape),
                        "data_offsets": [offset, offset + len(raw)]}
        chunks.append(raw)
        offset += len(raw)
    text = json.dumps(header, separators=(",", ":")).encode()
    text += b" " * ((8 - len(text) % 8) % 8)
    with open(path, "wb") as f:
        f.write(struct.pack("<Q", len(text)) + text + b"".join(chunks))


def export(path, directory):
    tensors, _ = load(path)
    try:
        import torch
    except ImportError:
        torch = None
    for name, array in tensors.items():
        if torch is not None:
            array = torch.from_numpy(array).numpy()
        np.save(f"{directory}/{name}.npy", array)
    print(f"exported {len(tensors)} tensors" + (" through torch" if torch else ""))


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "export":
        export(sys.argv[2], sys.argv[3])
        sys.exit(0)
    if len(sys.argv) != 3 or sys.argv[1] != "summary":
        print(__doc__)
        sys.exit(2)
    tensors, metadata = load(sys.argv[2])
    for k in sorted(metadata):
        print(f"meta {k}={metadata[k]}")
    for name in sorted(tensors):
        a = tensors[name]
        print(f"{name} {CODES[a.dtype]} {list(a.shape)} {float(a.astype(np.float64).sum()):.9g}")
