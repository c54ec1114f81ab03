#!/usr/bin/python3
"""Alignment from any pose: nurbsreg (global stage + exact ICP) vs Open3D (RANSAC on FPFH +
point-to-plane ICP on a dense model sampling, and FGR + ICP), on the same synthetic scans of
real CAD parts at random poses. Bounded: --trials poses per row (default 3). Prints a table:
success rate (rotation < 0.5 deg and translation < 1e-3 x model diagonal), median seconds
(model loading excluded for both: nurbsreg's "seconds" of the report minus nothing, it counts
the scan read; Open3D's from its feature computation on), median final errors, and nurbsreg's
exit-0-but-wrong count (must be 0).

  /usr/bin/python3 bench/align_global/run.py --nurbsreg build/bin/nurbsreg --trials 3 --threads 1

Needs python3-open3d and python3-numpy (Debian). The machine is shared: run the timed part
when it is quiet and say so.
"""
import argparse
import json
import os
import subprocess
import tempfile
import time

import numpy as np
import open3d as o3d

REAL = os.path.join(os.path.dirname(__file__), "../../../shared/data/real")
PARTS = {
    "nist": "nist/nist_ctc_02_asme1_ap242-1.stp",
    "linkrods": "occt/linkrods.step",
    "iea-blade": "iea-15mw/IEA_15MW_CFD.stp",
    "bearing": "occt/bearing.iges",
}
CONDITIONS = {"full": [], "outliers20": ["--outliers", "0.2"], "half": ["--view-fraction", "0.5"]}


def run(cmd):
    return subprocess.run(cmd, capture_output=True, text=True)


def errors(truth, found, diag):
    e = truth @ np.linalg.inv(found)
    ang = np.degrees(np.arccos(np.clip((np.trace(e[:3, :3]) - 1) / 2, -1, 1)))
    return ang, np.linalg.norm(e[:3, 3]) / diag


def open3d_align(scan_path, model_pcd, voxel, method, threads):
    src = o3d.io.read_point_cloud(scan_path)
    t0 = time.perf_counter()
    s = src.voxel_down_sample(voxel)
    t = model_pcd["down"]
    s.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * voxel, max_nn=30))
    fs = o3d.pipelines.registration.compute_fpfh_feature(
        s, o3d.geometry.KDTreeSearchParamHybrid(radius=5 * voxel, max_nn=100))
    ft = model_pcd["fpfh"]
    reg = o3d.pipelines.registration
    if method == "ransac":
        r = reg.registration_ransac_based_on_feature_matching(
            s, t, fs, ft, True, 1.5 * voxel,
            reg.TransformationEstimationPointToPoint(False), 3,
            [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
             reg.CorrespondenceCheckerBasedOnDistance(1.5 * voxel)],
            reg.RANSACConvergenceCriteria(100000, 0.999))
    else:
        r = reg.registration_fgr_based_on_feature_matching(
            s, t, fs, ft, reg.FastGlobalRegistrationOption(maximum_correspondence_distance=voxel))
    fine = reg.registration_icp(src, model_pcd["dense"], 1.0 * voxel, r.transformation,
                                reg.TransformationEstimationPointToPlane(),
                                reg.ICPConvergenceCriteria(max_iteration=50))
    return fine.transformation, time.perf_counter() - t0


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--nurbsreg", default="build/bin/nurbsreg")
    ap.add_argument("--trials", type=int, default=3)
    ap.add_argument("--points", type=int, default=50000)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--parts", default=",".join(PARTS))
    a = ap.parse_args()
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    rng = np.random.default_rng(1)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for part in a.parts.split(","):
            model = os.path.join(REAL, PARTS[part])
            info = run([a.nurbsreg, "info", "--model", model, "--json"])
            box = json.loads(info.stdout)["bounding_box"]
            diag = float(np.linalg.norm(np.array(box["max"]) - np.array(box["min"])))
            dense = os.path.join(tmp, part + ".dense.pcd")
            run([a.nurbsreg, "synth", "--model", model, "--points", "200000", "--out", dense])
            d = o3d.io.read_point_cloud(dense)
            d.estimate_normals()
            voxel = diag / 150.0
            down = d.voxel_down_sample(voxel)
            down.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * voxel, max_nn=30))
            fpfh = o3d.pipelines.registration.compute_fpfh_feature(
                down, o3d.geometry.KDTreeSearchParamHybrid(radius=5 * voxel, max_nn=100))
            mp = {"dense": d, "down": down, "fpfh": fpfh}
            for cond, extra in CONDITIONS.items():
                res = {k: [] for k in ("nurbsreg", "o3d-ransac", "o3d-fgr")}
                wrong_exit0 = 0
                for t in range(a.trials):
                    rot = rng.uniform(-180, 180, 3)
                    tr = rng.normal(size=3) * diag
                    pose = " ".join(f"{x:.6f}" for x in (*rot, *tr))
                    scan = os.path.join(tmp, "scan.pcd")
                    truth_path = os.path.join(tmp, "truth.txt")
                    run([a.nurbsreg, "synth", "--model", model, "--points", str(a.points),
                         "--noise", str(1e-4 * diag), "--pose", pose, "--seed", str(t + 1),
                         "--out", scan, "--out-pose", truth_path, *extra])
                    truth = np.loadtxt(truth_path)
                    out_pose = os.path.join(tmp, "found.txt")
                    report = os.path.join(tmp, "report.json")
                    for f in (out_pose, report):
                        if os.path.exists(f):
                            os.remove(f)
                    p = run([a.nurbsreg, "-q", "align", "--model", model, "--scan", scan,
                             "--threads", str(a.threads), "--out-pose", out_pose,
                             "--report", report])
                    if p.returncode == 0:
                        rep = json.load(open(report))
                        # The coarse and fine stages: the report's time less reading the model.
                        secs = rep["coarse"]["seconds"] + sum(h["seconds"] for h in rep["history"])
                        ang, te = errors(truth, np.loadtxt(out_pose), diag)
                        ok = ang < 0.5 and te < 1e-3
                        wrong_exit0 += not ok
                        res["nurbsreg"].append((ok, secs, ang, te))
                    else:
                        res["nurbsreg"].append((False, float("nan"), float("nan"), float("nan")))
                    for name, method in (("o3d-ransac", "ransac"), ("o3d-fgr", "fgr")):
                        T, secs = open3d_align(scan, mp, voxel, method, a.threads)
                        ang, te = errors(truth, np.asarray(T), diag)
                        res[name].append((ang < 0.5 and te < 1e-3, secs, ang, te))
                for name, r in res.items():
                    okc = sum(x[0] for x in r)
                    arr = np.array([x[1:] for x in r], dtype=float)
                    rows.append((part, cond, name, f"{okc}/{len(r)}", np.nanmedian(arr[:, 0]),
                                 np.nanmedian(arr[:, 1]), np.nanmedian(arr[:, 2]),
                                 wrong_exit0 if name == "nurbsreg" else "-"))
                    print("%-10s %-11s %-11s %6s %8.2f s %10.2e deg %10.2e diag  wrong-exit0 %s"
                          % rows[-1], flush=True)
    print("\npart       condition   method      success   median s   median rot   median trans")
    for r in rows:
        print("%-10s %-11s %-11s %6s %8.2f s %10.2e deg %10.2e diag  wrong-exit0 %s" % r)


if __name__ == "__main__":
    main()
