"""nurbsreg.align / Aligner: the CLI's pose and report, frame after frame, and the errors."""

import json

import numpy as np
import pytest

import nurbsreg
from conftest import PANEL, read_pose_file, run_cli


@pytest.fixture(scope="module")
def cli_alignment(panel_scan, tmp_path_factory):
    scan, _ = panel_scan
    d = tmp_path_factory.mktemp("align")
    run_cli("align", "--model", PANEL, "--scan", scan, "--out-pose", d / "pose.txt",
            "--report", d / "report.json")
    return read_pose_file(d / "pose.txt"), json.loads((d / "report.json").read_text())


@pytest.fixture(scope="module")
def scan_points(panel_scan):
    return nurbsreg.read_point_cloud(panel_scan[0]).points


def test_same_pose_and_report_as_the_cli(panel, scan_points, cli_alignment):
    pose, report = cli_alignment
    a = nurbsreg.align(panel, scan_points)
    np.testing.assert_array_equal(a.T_model_scan, pose)
    mine = a.report()
    for field in ("pose", "rms", "iterations", "converged", "inliers", "points",
                  "skipped_points", "method", "termination"):
        assert mine[field] == report[field], field
    assert [h["rms"] for h in mine["history"]] == [h["rms"] for h in report["history"]]


def test_result_fields(panel, panel_scan, scan_points):
    a = nurbsreg.align(panel, scan_points, distances=True)
    _, true_pose = panel_scan
    assert a.converged and a.termination == "converged"
    np.testing.assert_allclose(a.T_model_scan, true_pose, atol=5e-3)
    assert a.points == 20000 and a.skipped == 0
    assert a.fitness == a.inliers / a.points and 0.99 < a.fitness <= 1.0
    assert a.covariance.shape == (6, 6)
    np.testing.assert_allclose(a.covariance, a.covariance.T, rtol=1e-12, atol=0)
    assert not a.degeneracy["degenerate"] and a.degeneracy["free_directions"] == []
    assert len(a.history) == a.iterations and a.history[-1]["points"] == 20000
    assert a.deviation["count"] == 20000 and 0.015 < a.deviation["rms"] < 0.025
    # The per-point signed distances are the exact projections of the aligned scan (found from
    # warm hints: equal to a cold projection up to rounding).
    np.testing.assert_allclose(a.aligned, scan_points @ a.T_model_scan[:3, :3].T
                               + a.T_model_scan[:3, 3], rtol=0, atol=1e-12)
    exact = nurbsreg.project(panel, a.aligned)
    np.testing.assert_allclose(a.signed_distance, exact.signed_distance, rtol=0, atol=1e-12)
    assert nurbsreg.align(panel, scan_points).signed_distance is None


def test_frame_after_frame_keeps_one_aligner(panel, scan_points):
    aligner = nurbsreg.Aligner(panel)
    first = aligner.align(scan_points)
    # The next frame: the same part seen again, moved by a little more.
    c, s = np.cos(0.004), np.sin(0.004)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    frame = scan_points @ R.T + [0.3, -0.2, 0.1]
    warm = aligner.align(frame, first.T_model_scan)
    cold = nurbsreg.align(panel, frame, init=first.T_model_scan)
    # Warm hints only speed the projections up: the same pose (to rounding).
    np.testing.assert_allclose(warm.T_model_scan, cold.T_model_scan, rtol=0, atol=1e-9)
    assert warm.converged


def test_layouts_and_nan_rows(panel, scan_points):
    reference = nurbsreg.align(panel, scan_points)
    as_float32 = nurbsreg.align(panel, scan_points.astype(np.float32))  # the PCD's own values
    np.testing.assert_array_equal(as_float32.T_model_scan, reference.T_model_scan)
    fortran = nurbsreg.align(panel, np.asfortranarray(scan_points))
    np.testing.assert_array_equal(fortran.T_model_scan, reference.T_model_scan)
    holes = np.insert(scan_points, [0, 500, 20000], np.nan, axis=0)
    with_nan = nurbsreg.align(panel, holes, distances=True)
    assert with_nan.skipped == 3 and with_nan.points == 20000
    np.testing.assert_array_equal(with_nan.T_model_scan, reference.T_model_scan)
    assert np.isnan(with_nan.signed_distance[[0, 501, 20002]]).all()
    assert np.isnan(with_nan.aligned[501]).all() and with_nan.aligned.shape == (20003, 3)


def test_init_is_checked_as_the_cli_checks_init_files(panel, panel_scan, scan_points, tmp_path):
    sheared = np.eye(4)
    sheared[0, 1] = 0.1
    (tmp_path / "bad.txt").write_text("\n".join(" ".join(map(str, r)) for r in sheared))
    cli = run_cli("align", "--model", PANEL, "--scan", panel_scan[0], "--init",
                  tmp_path / "bad.txt", check=False)
    assert cli.returncode == 3
    with pytest.raises(nurbsreg.InputError) as caught:
        nurbsreg.align(panel, scan_points, init=sheared)
    assert isinstance(caught.value, ValueError)
    cli_reason = cli.stderr.strip().splitlines()[-1].split("bad.txt: ", 1)[1]
    assert str(caught.value) == "init: " + cli_reason
    with pytest.raises(ValueError, match=r"init: expected shape \(4, 4\)"):
        nurbsreg.align(panel, scan_points, init=np.eye(3))
    # A pose from a file with 6 decimals is accepted and made exactly rigid, as by the CLI.
    start = nurbsreg.align(panel, scan_points, init=np.round(np.eye(4), 6))
    assert start.converged


def test_failure_raises_with_the_cli_message(panel, scan_points, tmp_path):
    far = scan_points + [500.0, 0, 0]
    nurbsreg.write_point_cloud(tmp_path / "far.pcd", far, double_precision=True)
    # ICP from the identity (the global stage would find this pose): --no-global, init=eye.
    cli = run_cli("align", "--model", PANEL, "--scan", tmp_path / "far.pcd", "--max-distance", 2,
                  "--no-global", check=False)
    assert cli.returncode == 1
    with pytest.raises(nurbsreg.AlignmentError) as caught:
        nurbsreg.align(panel, far, init=np.eye(4), max_distance=2)
    cli_reason = cli.stderr.strip().splitlines()[-1].split("far.pcd: ", 1)[1]
    assert str(caught.value) == "scan: " + cli_reason
    assert caught.value.result.termination == "too_few_correspondences"
    assert not caught.value.result.converged


def test_bad_options(panel, scan_points):
    with pytest.raises(ValueError, match="keep_fraction"):
        nurbsreg.align(panel, scan_points, keep_fraction=0.0)
    with pytest.raises(ValueError, match='method: expected "point-to-plane" or "point-to-point"'):
        nurbsreg.align(panel, scan_points, method="plane")
    with pytest.raises(TypeError, match="max_iteration"):
        nurbsreg.align(panel, scan_points, max_iteration=3)
    with pytest.raises(ValueError, match="scan: no finite points to align"):
        nurbsreg.align(panel, np.full((5, 3), np.nan))
    with pytest.raises(ValueError, match="scan: no finite points to align"):
        nurbsreg.align(panel, np.zeros((0, 3)))
    with pytest.raises(ValueError, match=r"scan: expected shape \(N, 3\)"):
        nurbsreg.align(panel, np.zeros((5, 4)))


def test_options_reach_icp(panel, scan_points):
    # Two point-to-point iterations per stage from the identity stop short of the pose; the fit
    # verdict then judges it poor, and the error carries the run's result.
    with pytest.raises(nurbsreg.AlignmentError, match="poor fit") as caught:
        nurbsreg.align(panel, scan_points, init=np.eye(4), method="point-to-point",
                       max_iterations=2, coarse=[2000])
    a = caught.value.result
    assert a.report()["method"] == "point-to-point"
    assert a.termination == "max_iterations" and not a.converged and a.iterations == 4
