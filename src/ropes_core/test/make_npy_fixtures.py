#!/usr/bin/python3
"""Writes the .npy fixtures of npy_test.cpp with numpy (the witness for our reader and writer).

Run with Debian's python3 and python3-numpy from this folder:
    /usr/bin/python3 make_npy_fixtures.py
Each array's values are simple formulas that the C++ test recomputes.
"""
import numpy as np

arrays = {
    "u8_2x3.npy": np.arange(6, dtype=np.uint8).reshape(2, 3) * 40,
    "i32_4.npy": np.array([-2, -1, 0, 2147483647], dtype=np.int32),
    "i64_2x2.npy": np.array([[-(2**40), 1], [2, 2**62]], dtype=np.int64),
    "f32_2x3x4.npy": (np.arange(24, dtype=np.float32).reshape(2, 3, 4) - 11.5) / 4,
    "f64_scalar.npy": np.array(np.pi, dtype=np.float64),
    "f32_0.npy": np.zeros((0,), dtype=np.float32),
}
for name, a in arrays.items():
    np.save(f"fixtures/{name}", a)
    print(name, a.dtype, a.shape)
