#!/usr/bin/python3
"""nurbsreg's exact signed distances against CloudCompare's C2M distances on the same points.

Usage: compare_c2m.py deviations.ply cc_c2m.ply
Both are binary PLY files with one vertex per point in the same order (CloudCompare keeps the
loaded cloud's order and adds its distance as a scalar field).
"""
import re
import sys

import numpy as np


def read_ply(path):
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header") + len(b"end_header")
    end = data.index(b"\n", end) + 1
    header = data[:end].decode(errors="replace")
    types = {"float": "<f4", "float32": "<f4", "double": "<f8", "float64": "<f8", "uchar": "u1",
             "uint8": "u1", "char": "i1", "int8": "i1", "int": "<i4", "int32": "<i4",
             "uint": "<u4", "uint32": "<u4", "short": "<i2", "ushort": "<u2"}
    vertex = header.split("element vertex")[1]
    count = int(vertex.split()[0])
    block = vertex.split("element")[0]
    fields = [(name, types[t]) for t, name in re.findall(r"property (\w+) (\S+)", block)]
    return np.frombuffer(data[end:], dtype=np.dtype(fields), count=count)


ours = read_ply(sys.argv[1])
cc = read_ply(sys.argv[2])
names = [n for n in cc.dtype.names if "C2M" in n or "distances" in n.lower()]
if not names:
    sys.exit(f"no C2M field in {sys.argv[2]}: {cc.dtype.names}")
d_cc = cc[names[-1]].astype(np.float64)
d = ours["signed_distance"].astype(np.float64)
if len(d) != len(d_cc):
    sys.exit(f"point counts differ: {len(d)} vs {len(d_cc)}")
diff = d_cc - d
absdiff = np.abs(diff)
sign_flip = np.mean(np.sign(d_cc) != np.sign(d))
print(f"  CloudCompare field: {names[-1]}")
print(f"  |C2M - exact|: mean {absdiff.mean():.3g}  p50 {np.percentile(absdiff, 50):.3g}  "
      f"p95 {np.percentile(absdiff, 95):.3g}  p99 {np.percentile(absdiff, 99):.3g}  max {absdiff.max():.3g} mm")
print(f"  |C2M| - |exact| (mesh chord error moves distances): mean {(np.abs(d_cc) - np.abs(d)).mean():+.3g} mm")
print(f"  sign disagrees on {100 * sign_flip:.2f} % of the points (points closer to the surface than the mesh error)")
for band in (0.05,):
    ours_in = np.mean(np.abs(d) <= band)
    cc_in = np.mean(np.abs(d_cc) <= band)
    print(f"  inside +-{band}: exact {100 * ours_in:.3f} %, C2M {100 * cc_in:.3f} %")
