#!/usr/bin/env python3
"""Error of ember bakes against a reference bake of the same scene (more samples, another
seed): for each PLY, the mean over vertex keys and channels of the squared error (MSE) and of
the squared error relative to the reference value squared plus 0.01 (relMSE, as `ember bench`
defines it for pixels). Both are over the distinct vertex positions, so duplicated face
corners do not weigh twice; the reference's own noise adds to both equally.

Usage: error.py REF.ply BAKE.ply..."""
import struct
import sys


def load(path):
    """{(x, y, z, nx, ny, nz): (r, g, b)} of a binary little-endian PLY written by `ember bake`."""
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().split("\n")
    props = [line.split()[2] for line in header if line.startswith("property float")]
    want = ["x", "y", "z", "nx", "ny", "nz", "red", "green", "blue"]
    if props[: len(want)] != want:
        sys.exit(f"error: {path}: expected float properties {want}, found {props}")
    count = next(int(line.split()[2]) for line in header if line.startswith("element vertex"))
    stride = 4 * len(props)
    out = {}
    for i in range(count):
        v = struct.unpack_from("<9f", data, end + i * stride)
        out[v[:6]] = v[6:]
    return out


ref = load(sys.argv[1])
for path in sys.argv[2:]:
    bake = load(path)
    if bake.keys() != ref.keys():
        sys.exit(f"error: {path} has other vertices than {sys.argv[1]}")
    se = rel = 0.0
    for key, r in ref.items():
        for a, b in zip(bake[key], r):
            se += (a - b) ** 2
            rel += (a - b) ** 2 / (b * b + 0.01)
    n = 3 * len(ref)
    print(f"{path} {se / n:.4e} {rel / n:.4e}")
