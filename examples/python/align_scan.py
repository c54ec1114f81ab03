"""Align a scan to a CAD model and print the pose and the deviation summary.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/align_scan.py \
        examples/panel.json [scan.pcd]

Without a scan file it aligns a synthetic scan of the model (moved 3/-2/4 degrees and
(3, -2, 2) mm, 0.02 mm noise), as scripts/demo.sh does with the CLI.
"""

import sys

import numpy as np

import nurbsreg

model = nurbsreg.load_model(sys.argv[1])
if len(sys.argv) > 2:
    scan = nurbsreg.read_point_cloud(sys.argv[2]).points
    print(f"{sys.argv[2]}: {len(scan)} points")
else:
    synthetic = nurbsreg.synth(model, 200_000, noise=0.02, pose=(3, -2, 4, 3, -2, 2), seed=7)
    scan = synthetic.points
    print(f"synthetic scan: {len(scan)} points")

# No init: from any pose (the global stage, then ICP), as `nurbsreg align` without --init. A
# poor fit raises nurbsreg.PoorFitError (the CLI's exit 1) unless accept_poor=True.
result = nurbsreg.align(model, scan)
np.set_printoptions(precision=6, suppress=True)
print("pose (model_point = T * scan_point):")
print(result.T_model_scan)
print(f"rms {result.rms:.6g} over {result.inliers}/{result.points} inliers "
      f"(fitness {result.fitness:.4f}), {result.iterations} iterations, {result.termination}")
d = result.deviation
print(f"deviation |d| of {d['count']} points: mean {d['mean']:.4g}  rms {d['rms']:.4g}  "
      f"median {d['median']:.4g}  p95 {d['p95']:.4g}  p99 {d['p99']:.4g}  max {d['max']:.4g} "
      f"{model.units}")
fit = result.fit
# Where the tolerance came from (a scan whose noise could not be estimated gets a floor).
basis = (f"{fit.tolerance / fit.noise:.3g} x noise {fit.noise:.3g}" if fit.noise > 0
         else "noise not estimated: the model's floor")
print(f"fit {fit.fit}: {100 * fit.inlier_fraction:.1f}% of the points within {fit.tolerance:.3g} "
      f"({basis}), rms {fit.rms:.3g}, model coverage {100 * fit.coverage:.1f}%")
if result.coarse is not None:
    c = result.coarse
    print(f"coarse: {c.method}, {c.verified} hypotheses verified in {c.seconds:.2f} s; winner "
          f"{100 * c.winner.inlier_fraction:.1f}% inliers")
if result.degeneracy["degenerate"]:
    print("unconstrained:", result.degeneracy["description"])
