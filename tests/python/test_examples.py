"""The scripts in examples/python/ run and write what they say."""

import os
import re
import subprocess
import sys

import numpy as np

import nurbsreg
from conftest import EXAMPLES, PANEL, PANEL_SCAN_POINTS, sized

SCRIPTS = EXAMPLES / "python"
# A hang detector: under sanitizers (conftest.REDUCED) an alignment takes minutes.
TIMEOUT = sized(120, 900)


def run_script(name, *args):
    done = subprocess.run([sys.executable, str(SCRIPTS / name), *map(str, args)],
                          capture_output=True, text=True, env=os.environ, timeout=TIMEOUT)
    assert done.returncode == 0, done.stderr
    return done.stdout


def test_align_scan_prints_pose_and_deviations(panel_scan):
    out = run_script("align_scan.py", PANEL, panel_scan[0])
    assert "pose (model_point = T * scan_point):" in out
    assert re.search(rf"rms 0\.0\d+ over \d+/{PANEL_SCAN_POINTS} inliers .* converged", out), out
    assert f"deviation |d| of {PANEL_SCAN_POINTS} points" in out
    assert re.search(r"fit good: 99\.\d% of the points", out), out
    assert "coarse: fpfh-ransac" in out


def test_inspect_scan_saves_the_coloured_cloud(panel, panel_scan, tmp_path):
    out = run_script("inspect_scan.py", PANEL, panel_scan[0], 0.05, tmp_path / "d.ply",
                     tmp_path / "r.html")
    assert re.search(rf"\d+\.\d\d % of {PANEL_SCAN_POINTS} points inside \[-0\.05, \+0\.05\] mm",
                     out), out
    assert "signed deviation: mean" in out and "fit good" in out
    expected = nurbsreg.inspect(panel, panel_scan[0], tolerance=0.05, ply=tmp_path / "e.ply")
    assert (tmp_path / "d.ply").read_bytes() == (tmp_path / "e.ply").read_bytes()
    assert ("PASS" if expected.passed else "FAIL") in out
    assert (tmp_path / "r.html").stat().st_size > 10000


def test_project_to_ply_writes_scalar_fields(panel, tmp_path):
    points = nurbsreg.synth(panel, 1000, noise=0.1, seed=2).points
    points[7] = np.nan
    nurbsreg.write_point_cloud(tmp_path / "p.pcd", points, double_precision=True)
    out = run_script("project_to_ply.py", PANEL, tmp_path / "p.pcd", tmp_path / "d.ply")
    assert "999 points (1 skipped)" in out
    data = (tmp_path / "d.ply").read_bytes()
    header, body = data.split(b"end_header\n", 1)
    assert b"property float signed_distance" in header and b"property int face" in header
    vertex = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("signed_distance", "<f4"),
                       ("distance", "<f4"), ("face", "<i4"), ("u", "<f8"), ("v", "<f8")])
    rows = np.frombuffer(body, vertex)
    keep = np.arange(1000) != 7
    expected = nurbsreg.project(panel, points[keep])
    np.testing.assert_array_equal(rows["distance"], expected.distance.astype(np.float32))
    np.testing.assert_array_equal(rows["u"], expected.u)
    # nurbsreg reads its own PLY back (x y z of every vertex).
    back = nurbsreg.read_point_cloud(tmp_path / "d.ply").points
    np.testing.assert_array_equal(back, points[keep].astype(np.float32))
