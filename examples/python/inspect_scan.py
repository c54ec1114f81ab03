"""Inspect a scan against a CAD model: align it, then save the coloured deviation cloud (PLY for
CloudCompare, MeshLab, Open3D) and print the verdict and the deviation summary.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/inspect_scan.py \
        examples/panel.json scan.pcd 0.05 deviations.ply [report.html]

The tolerance is the band [-t, +t] in model units. The PLY holds per point x y z, the colour,
signed_distance, face, u, v, tolerance (-1 below, 0 inside, +1 above) and the point's index in
the scan file, as `nurbsreg inspect` writes D/deviations.ply.
"""

import sys

import nurbsreg

model_path, scan_path, tolerance, ply_path = sys.argv[1:5]
html_path = sys.argv[5] if len(sys.argv) > 5 else None
model = nurbsreg.load_model(model_path)
r = nurbsreg.inspect(model, scan_path, tolerance=float(tolerance), ply=ply_path, html=html_path)

a = r.alignment
print(f"aligned: rms {a.rms:.4g} over {a.inliers}/{a.points} inliers, fit {a.fit.fit} "
      f"({100 * a.fit.inlier_fraction:.1f}% within {a.fit.tolerance:.3g} {model.units})")
s = r.summary
low, high = r.tolerance
print(f"{100 * s['inside_tolerance']:.2f} % of {s['points']} points inside [{low:+g}, {high:+g}] "
      f"{model.units} ({s['above']} above, {s['below']} below): "
      f"{'PASS' if r.passed else 'FAIL'}")
print(f"signed deviation: mean {s['mean']:+.4g}  std {s['std']:.4g}  min {s['min']:+.4g}  "
      f"max {s['max']:+.4g}  p5 {s['p5']:+.4g}  p95 {s['p95']:+.4g}")
worst = max(r.faces, key=lambda f: f["rms"] if f["points"] else -1)
print(f"worst face: {worst['face']} {worst['name']!r}, rms {worst['rms']:.4g}")
print("wrote", ply_path, *(html_path,) * (html_path is not None))
