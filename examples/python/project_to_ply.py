"""Project a point cloud onto a CAD model and save the points with their distances as a binary
PLY with scalar fields (CloudCompare, ParaView and MeshLab show them as colour maps).

    PYTHONPATH=build/python /usr/bin/python3 examples/python/project_to_ply.py \
        examples/panel.json points.pcd distances.ply

Fields per vertex: x y z (float), signed_distance, distance (float), face (int: the surface
index), u v (double). Points that could not be projected (NaN rows) are left out.
"""

import os
import sys
import tempfile

import numpy as np

import nurbsreg

model_path, points_path, out_path = sys.argv[1:4]
model = nurbsreg.load_model(model_path)
cloud = nurbsreg.read_point_cloud(points_path)
r = nurbsreg.project(model, cloud.points)
ok = r.status == nurbsreg.STATUS_OK

vertex = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("signed_distance", "<f4"),
                   ("distance", "<f4"), ("face", "<i4"), ("u", "<f8"), ("v", "<f8")])
rows = np.empty(int(ok.sum()), vertex)
for k, axis in enumerate("xyz"):
    rows[axis] = cloud.points[ok, k]
rows["signed_distance"] = r.signed_distance[ok]
rows["distance"] = r.distance[ok]
rows["face"] = r.entity[ok]
rows["u"], rows["v"] = r.u[ok], r.v[ok]

ply_types = {"<f4": "float", "<f8": "double", "<i4": "int"}
header = ["ply", "format binary_little_endian 1.0", f"element vertex {len(rows)}"]
header += [f"property {ply_types[vertex[name].str]} {name}" for name in vertex.names]
header += ["end_header"]
# Written to a temporary file beside the target and renamed: no partial file on failure.
fd, tmp = tempfile.mkstemp(dir=os.path.dirname(os.path.abspath(out_path)), suffix=".ply")
try:
    with os.fdopen(fd, "wb") as f:
        f.write(("\n".join(header) + "\n").encode("ascii"))
        rows.tofile(f)
    os.replace(tmp, out_path)
except BaseException:
    os.unlink(tmp)
    raise
d = r.distance[ok]
summary = f", distance mean {d.mean():.4g} max {d.max():.4g} {model.units}" if len(d) else ""
print(f"{out_path}: {len(rows)} points ({cloud.skipped} skipped){summary}")
