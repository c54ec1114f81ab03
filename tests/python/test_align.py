"""nurbsreg.align / Aligner: the CLI's pose and report, frame after frame, and the errors."""

import json

import numpy as np
import pytest

import nurbsreg
from conftest import (EXAMPLES, PANEL, PANEL_SCAN_POINTS, read_pose_file, run_cli, sized,
                      without_times)


def cli_align(scan, out, *options, model=PANEL):
    """`nurbsreg align` with `options`: (pose, report dict), or (None, report, stderr's last
    line) when it exits 1."""
    done = run_cli("align", "--model", model, "--scan", scan, "--out-pose", out / "pose.txt",
                   "--report", out / "report.json", *options, check=False)
    report = json.loads((out / "report.json").read_text())
    if done.returncode == 1:
        return None, report, done.stderr.strip().splitlines()[-1]
    assert done.returncode == 0, done.stderr
    return read_pose_file(out / "pose.txt"), report, None


def write_pose(path, T):
    """A pose file with every number in its exact (repr) form: --init reads back these bits."""
    path.write_text("\n".join(" ".join(repr(float(x)) for x in row) for row in T) + "\n")


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
    # The whole report, field for field (io::make_alignment_report), but for the wall times.
    assert without_times(a.report()) == without_times(report)
    assert json.loads(a.to_json()) == a.report()
    assert "coarse" in report and "fit_details" in report


def test_fit_verdict_and_coarse_stage_are_the_reports(panel, scan_points, cli_alignment):
    _, report = cli_alignment
    a = nurbsreg.align(panel, scan_points)
    assert isinstance(a.fit, nurbsreg.FitVerdict) and a.fit.fit == "good" and a.fit.good
    details = report["fit_details"]
    assert report["fit"] == a.fit.fit
    for field in ("noise", "tolerance", "inlier_fraction", "rms", "rms_over_noise",
                  "coverage"):
        assert getattr(a.fit, field) == details[field], field
    assert a.fit.reason == ""
    c, expected = a.coarse, report["coarse"]
    assert isinstance(c, nurbsreg.CoarseReport) and c.method == expected["method"]
    assert (c.hypotheses, c.verified) == (expected["hypotheses"], expected["verified"])
    assert c.winner.inlier_fraction == expected["winner"]["inlier_fraction"]
    np.testing.assert_array_equal(c.winner.T_model_scan, expected["winner"]["pose"])
    assert (c.runner_up is None) == (expected["runner_up"] is None)
    assert c.alternatives == [] and c.symmetry == "" and c.seconds > 0


@pytest.mark.parametrize("model_name", ["panel.json", "folded.json"])
def test_init_gives_the_cli_init_pose_bits(model_name, tmp_path):
    model_path = EXAMPLES / model_name
    model = nurbsreg.load_model(model_path)
    scan = tmp_path / "scan.pcd"
    run_cli("synth", "--model", model_path, "--points", sized(8000, 3000), "--noise", 0.02,
            "--seed", 5, "--pose", "3 -2 1 1.5 -1 0.5", "--out", scan)
    points = nurbsreg.read_point_cloud(scan).points
    # A start near the truth, not exactly orthonormal (as a pose printed by another tool).
    c, s = np.cos(0.03), np.sin(0.03)
    init = np.array([[c, -s, 0, -1.2], [s, c, 0, 0.8], [0, 0, 1, -0.3], [0, 0, 0, 1]])
    init[0, 0] += 2e-7
    write_pose(tmp_path / "init.txt", init)
    pose, report, _ = cli_align(scan, tmp_path, "--init", tmp_path / "init.txt", model=model_path)
    a = nurbsreg.align(model, points, init=init)
    np.testing.assert_array_equal(a.T_model_scan, pose)
    assert without_times(a.report()) == without_times(report)
    assert a.coarse is None and "coarse" not in report and a.fit.fit == report["fit"]
    # And from any pose (no init: the global stage), on this model too: the same pose, or the
    # same failure (the folded part's poor fit from any pose) as the CLI's exit 1.
    (tmp_path / "any").mkdir()
    pose, report, cli_line = cli_align(scan, tmp_path / "any", model=model_path)
    if pose is None:
        with pytest.raises(nurbsreg.AlignmentError) as caught:
            nurbsreg.align(model, points)
        assert str(caught.value) == "scan: " + cli_line.split("scan.pcd: ", 1)[1]
        a = caught.value.result
    else:
        a = nurbsreg.align(model, points)
        np.testing.assert_array_equal(a.T_model_scan, pose)
    assert without_times(a.report()) == without_times(report)


def test_no_global_is_icp_from_the_identity(panel, panel_scan, scan_points, tmp_path):
    pose, report, _ = cli_align(panel_scan[0], tmp_path, "--no-global")
    a = nurbsreg.align(panel, scan_points, global_alignment=False)
    np.testing.assert_array_equal(a.T_model_scan, pose)
    assert without_times(a.report()) == without_times(report) and a.coarse is None
    np.testing.assert_array_equal(
        nurbsreg.align(panel, scan_points, init=np.eye(4)).T_model_scan, pose)
    with pytest.raises(ValueError, match="init and global_alignment=True contradict"):
        nurbsreg.align(panel, scan_points, init=np.eye(4), global_alignment=True)
    with pytest.raises(TypeError, match="global_alignment"):
        nurbsreg.align(panel, scan_points, global_alignment="yes")


def test_poor_fit_raises_unless_accepted_as_the_cli_exits(panel, panel_scan, scan_points,
                                                          tmp_path):
    # Every point must be within 3 sigma for a good fit: this noisy scan's is poor.
    strict = ("--min-inlier-fraction", "1")
    _, report, cli_line = cli_align(panel_scan[0], tmp_path, *strict)
    with pytest.raises(nurbsreg.PoorFitError) as caught:
        nurbsreg.align(panel, scan_points, min_inlier_fraction=1.0)
    assert isinstance(caught.value, nurbsreg.AlignmentError)
    assert str(caught.value) == "scan: " + cli_line.split("scan.pcd: ", 1)[1]
    poor = caught.value.result
    assert poor.fit.fit == "poor" and poor.fit.reason and poor.fit.inlier_fraction < 1.0
    assert without_times(poor.report()) == without_times(report)

    pose, report, _ = cli_align(panel_scan[0], tmp_path, *strict, "--accept-poor")
    with pytest.warns(nurbsreg.NurbsregWarning, match="accepted although"):
        accepted = nurbsreg.align(panel, scan_points, min_inlier_fraction=1.0, accept_poor=True)
    np.testing.assert_array_equal(accepted.T_model_scan, pose)
    assert accepted.fit.fit == "poor" == report["fit"] and accepted.failure is None
    assert without_times(accepted.report()) == without_times(report)
    with pytest.raises(ValueError, match=r"min_inlier_fraction: must be in \[0, 1\]"):
        nurbsreg.align(panel, scan_points, min_inlier_fraction=1.5)


def test_result_fields(panel, panel_scan, scan_points):
    a = nurbsreg.align(panel, scan_points, distances=True)
    _, true_pose = panel_scan
    assert a.converged and a.termination == "converged"
    # The pose error grows as 1/sqrt(points): the sanitizers' quarter of the scan doubles it.
    np.testing.assert_allclose(a.T_model_scan, true_pose, atol=sized(5e-3, 1.5e-2))
    assert a.points == PANEL_SCAN_POINTS and a.skipped == 0
    assert a.fitness == a.inliers / a.points and 0.99 < a.fitness <= 1.0
    assert a.covariance.shape == (6, 6)
    np.testing.assert_allclose(a.covariance, a.covariance.T, rtol=1e-12, atol=0)
    assert not a.degeneracy["degenerate"] and a.degeneracy["free_directions"] == []
    assert len(a.history) == a.iterations and a.history[-1]["points"] == PANEL_SCAN_POINTS
    assert a.deviation["count"] == PANEL_SCAN_POINTS and 0.015 < a.deviation["rms"] < 0.025
    # The per-point signed distances are the exact projections of the aligned scan (found from
    # warm hints: equal to a cold projection up to rounding).
    np.testing.assert_allclose(a.aligned, scan_points @ a.T_model_scan[:3, :3].T
                               + a.T_model_scan[:3, 3], rtol=0, atol=1e-12)
    exact = nurbsreg.project(panel, a.aligned)
    np.testing.assert_allclose(a.signed_distance, exact.signed_distance, rtol=0, atol=1e-12)
    assert nurbsreg.align(panel, scan_points).signed_distance is None


def test_model_features_come_from_the_cache_once_per_loaded_model(scan_points, tmp_path,
                                                                  monkeypatch, cli_alignment):
    # As `nurbsreg align` does: from any pose the model's features are read from the features
    # cache, or built and stored there, once per loaded model (every Aligner made from it, and
    # nurbsreg.align's one per call, share them); NURBSREG_NO_CACHE leaves the cache alone.
    pose, _ = cli_alignment
    monkeypatch.setenv("NURBSREG_CACHE_DIR", str(tmp_path / "cache"))
    model = nurbsreg.load_model(PANEL)
    first = nurbsreg.align(model, scan_points)
    stored = sorted((tmp_path / "cache").glob("*.nrbfeat"))
    assert len(stored) == 1
    written = stored[0].stat().st_mtime_ns
    again = nurbsreg.align(model, scan_points)
    # Another process (a model loaded afresh) reads them: the entry is not written again.
    from_disk = nurbsreg.align(nurbsreg.load_model(PANEL), scan_points)
    assert stored[0].stat().st_mtime_ns == written
    for a in (first, again, from_disk):
        np.testing.assert_array_equal(a.T_model_scan, pose)
    monkeypatch.setenv("NURBSREG_NO_CACHE", "1")
    monkeypatch.setenv("NURBSREG_CACHE_DIR", str(tmp_path / "off"))
    off = nurbsreg.align(nurbsreg.load_model(PANEL), scan_points)
    np.testing.assert_array_equal(off.T_model_scan, pose)
    assert not (tmp_path / "off").exists() or not any((tmp_path / "off").glob("*.nrbfeat"))
    # From a given pose nothing is built for the global stage: no entry.
    monkeypatch.delenv("NURBSREG_NO_CACHE")
    monkeypatch.setenv("NURBSREG_CACHE_DIR", str(tmp_path / "init"))
    nurbsreg.align(nurbsreg.load_model(PANEL), scan_points, init=pose)
    assert not any((tmp_path / "init").glob("*.nrbfeat"))


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
    strided32 = np.repeat(scan_points.astype(np.float32), 2, axis=0)[::2]
    assert not strided32.flags.c_contiguous
    np.testing.assert_array_equal(nurbsreg.align(panel, strided32).T_model_scan,
                                  reference.T_model_scan)
    n = PANEL_SCAN_POINTS
    holes = np.insert(scan_points, [0, 500, n], np.nan, axis=0)
    with_nan = nurbsreg.align(panel, holes, distances=True)
    assert with_nan.skipped == 3 and with_nan.points == n
    np.testing.assert_array_equal(with_nan.T_model_scan, reference.T_model_scan)
    assert np.isnan(with_nan.signed_distance[[0, 501, n + 2]]).all()
    assert np.isnan(with_nan.aligned[501]).all() and with_nan.aligned.shape == (n + 3, 3)


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
    with pytest.raises(nurbsreg.PoorFitError, match="poor fit") as caught:
        nurbsreg.align(panel, scan_points, init=np.eye(4), method="point-to-point",
                       max_iterations=2, coarse=[2000])
    a = caught.value.result
    assert a.report()["method"] == "point-to-point"
    assert a.termination == "max_iterations" and not a.converged and a.iterations == 4
