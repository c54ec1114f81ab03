"""nurbsreg.project: the CLI's rows, every accepted array layout, and the errors."""

import json

import numpy as np
import pytest

import nurbsreg
from conftest import EXAMPLES, PANEL, PANEL_SCAN_POINTS, read_csv_columns, run_cli


def test_same_rows_as_the_cli(panel, panel_scan, tmp_path):
    scan, _ = panel_scan
    out = tmp_path / "r.csv"
    run_cli("project", "--model", PANEL, "--points", scan, "--out", out)
    cli = read_csv_columns(out)
    cloud = nurbsreg.read_point_cloud(scan)
    r = nurbsreg.project(panel, cloud.points)
    assert len(r) == len(cli["index"]) == PANEL_SCAN_POINTS
    np.testing.assert_array_equal(cloud.index, cli["index"])
    np.testing.assert_array_equal(cloud.points, np.c_[cli["x"], cli["y"], cli["z"]])
    np.testing.assert_array_equal(r.foot, np.c_[cli["foot_x"], cli["foot_y"], cli["foot_z"]])
    np.testing.assert_array_equal(r.normal,
                                  np.c_[cli["normal_x"], cli["normal_y"], cli["normal_z"]])
    for name in ("distance", "entity", "u", "v", "signed_distance"):
        np.testing.assert_array_equal(getattr(r, name), cli[name], err_msg=name)
    assert (r.status == nurbsreg.STATUS_OK).all() and r.skipped == 0


def test_curves_same_rows_as_the_cli(tmp_path):
    model = nurbsreg.load_model(EXAMPLES / "curves.json")
    points = np.random.default_rng(5).uniform(-40, 40, (500, 3))
    nurbsreg.write_point_cloud(tmp_path / "p.xyz", points, double_precision=True)
    out = tmp_path / "r.csv"
    run_cli("project", "--model", EXAMPLES / "curves.json", "--points", tmp_path / "p.xyz",
            "--out", out, "--target", "curves")
    cli = read_csv_columns(out)
    r = nurbsreg.project(model, points, target="curves")
    for name in ("distance", "entity", "u", "v"):
        np.testing.assert_array_equal(getattr(r, name), cli[name], err_msg=name)
    np.testing.assert_array_equal(r.foot, np.c_[cli["foot_x"], cli["foot_y"], cli["foot_z"]])


@pytest.fixture(scope="module")
def points():
    rng = np.random.default_rng(11)
    # float32-exact values, so the float32 variant holds the same points.
    return rng.uniform([0, 0, -5], [100, 100, 20], (3000, 3)).astype(np.float32).astype(np.float64)


@pytest.fixture(scope="module")
def reference(panel, points):
    return nurbsreg.project(panel, points)


def layouts(points):
    wide = np.zeros((len(points), 6))
    wide[:, ::2] = points
    yield "float32", points.astype(np.float32)
    yield "fortran", np.asfortranarray(points)
    yield "column-strided", wide[:, ::2]
    yield "row-strided", np.repeat(points, 2, axis=0)[::2]
    yield "transposed", np.ascontiguousarray(points.T).T
    yield "reversed", points[::-1][::-1]
    yield "float32-fortran", np.asfortranarray(points.astype(np.float32))
    yield "list", points.tolist()
    raw = np.empty(points.size * 8 + 1, np.uint8)
    unaligned = raw[1:].view(np.float64).reshape(-1, 3)
    unaligned[:] = points
    assert not unaligned.flags.aligned
    yield "unaligned", unaligned


@pytest.mark.parametrize("layout", [name for name, _ in layouts(np.zeros((1, 3)))])
def test_every_layout_gives_the_same_answers(panel, points, reference, layout):
    array = dict(layouts(points))[layout]
    r = nurbsreg.project(panel, array)
    for name in ("foot", "distance", "signed_distance", "entity", "u", "v", "normal", "status"):
        np.testing.assert_array_equal(getattr(r, name), getattr(reference, name), err_msg=name)


def test_results_are_read_only_views(reference):
    with pytest.raises(ValueError):
        reference.distance[0] = 0.0
    assert reference.foot.shape == (3000, 3) and reference.foot.dtype == np.float64
    assert reference.entity.dtype == np.int32 and reference.status.dtype == np.uint8
    assert reference.foot.base is not None  # a view of the engine's array, not a copy


def test_empty_frame(panel):
    r = nurbsreg.project(panel, np.zeros((0, 3)))
    assert len(r) == 0 and r.skipped == 0
    assert r.foot.shape == (0, 3) and r.distance.shape == (0,)


def test_nan_rows_are_skipped_and_counted(panel, points, reference):
    bad = points.copy()
    bad[[3, 17, 2999], 1] = np.nan
    bad[100, 0] = np.inf
    r = nurbsreg.project(panel, bad)
    skipped = np.zeros(len(points), bool)
    skipped[[3, 17, 2999, 100]] = True
    assert r.skipped == 4
    np.testing.assert_array_equal(r.status == nurbsreg.STATUS_SKIPPED, skipped)
    assert np.isnan(r.distance[skipped]).all() and (r.entity[skipped] == -1).all()
    np.testing.assert_array_equal(r.distance[~skipped], reference.distance[~skipped])
    np.testing.assert_array_equal(r.foot[~skipped], reference.foot[~skipped])


def test_thread_count_does_not_change_answers(panel, points, reference):
    r = nurbsreg.project(panel, points, threads=1)
    np.testing.assert_array_equal(r.foot, reference.foot)
    np.testing.assert_array_equal(r.u, reference.u)


def test_hints_and_certificates_give_the_same_closest_points(panel, points, reference):
    first = nurbsreg.project(panel, points, certify=True)
    np.testing.assert_array_equal(first.distance, reference.distance)
    moved = points + np.array([0.01, -0.02, 0.015])
    cold = nurbsreg.project(panel, moved)
    warm = nurbsreg.project(panel, moved, hints=first, certify=True)
    # The same foot on the same surface; Newton from the hint instead of the cold seed ends
    # within its tolerance of the cold answer.
    np.testing.assert_array_equal(warm.entity, cold.entity)
    for name in ("foot", "distance", "u", "v"):
        np.testing.assert_allclose(getattr(warm, name), getattr(cold, name), rtol=0, atol=1e-8,
                                   err_msg=name)
    with pytest.raises(ValueError, match="hints: 3000 results for 10 points"):
        nurbsreg.project(panel, points[:10], hints=first)


@pytest.mark.parametrize("bad, error, text", [
    (np.zeros((4, 3), np.int64), TypeError,
     "points: expected float64 or float32 values, got int64"),
    (np.zeros((4, 3), np.float16), TypeError, "points: expected float64 or float32"),
    (np.zeros((4, 2)), ValueError, r"points: expected shape \(N, 3\), got \(4, 2\)"),
    (np.zeros(3), ValueError, r"points: expected shape \(N, 3\), got \(3,\)"),
    (np.zeros((2, 3, 1)), ValueError, r"points: expected shape \(N, 3\), got \(2, 3, 1\)"),
    ("not points", TypeError, "points: expected an \\(N, 3\\) float64 or float32 array, got str"),
    ([[1, 2], [3]], TypeError, "points: expected an \\(N, 3\\)"),
])
def test_bad_points_name_the_argument(panel, bad, error, text):
    with pytest.raises(error, match=text):
        nurbsreg.project(panel, bad)


def test_bad_options_name_the_argument(panel, points):
    with pytest.raises(ValueError, match='target: expected "surfaces" or "curves", got "edges"'):
        nurbsreg.project(panel, points, target="edges")
    with pytest.raises(ValueError, match="the model has no curves; use target=\"surfaces\""):
        nurbsreg.project(panel, points, target="curves")
    with pytest.raises(ValueError, match="threads: must be >= 0"):
        nurbsreg.project(panel, points, threads=-1)


def test_scan_far_larger_than_the_model_warns_as_the_cli(panel):
    with pytest.warns(nurbsreg.NurbsregWarning, match="the scan is .* times the size of the model"):
        nurbsreg.project(panel, np.array([[0.0, 0, 0], [5000, 5000, 5000]]))


def test_points_far_from_the_model_warn_as_the_cli(panel, panel_scan, tmp_path):
    """A scan still in the scanner's frame: the CLI's line, word for word; in its frame: quiet."""
    scan, _ = panel_scan
    points = nurbsreg.read_point_cloud(scan).points + np.array([1000.0, 0.0, 0.0])
    moved = tmp_path / "moved.xyz"
    nurbsreg.write_point_cloud(moved, points, double_precision=True)
    cli = run_cli("project", "--model", PANEL, "--points", str(moved),
                  "--out", str(tmp_path / "r.csv"))
    cli_lines = [line for line in cli.stderr.splitlines() if "half of the points lie" in line]
    assert len(cli_lines) == 1, cli.stderr
    with pytest.warns(nurbsreg.NurbsregWarning, match="is the scan in the model's frame") as caught:
        nurbsreg.project(panel, points)
    notes = [str(w.message) for w in caught if "half of the points lie" in str(w.message)]
    assert len(notes) == 1
    assert notes[0].split("points: ", 1)[1] in cli_lines[0]
    assert not any("half of the points" in w for w in nurbsreg.project(panel, points - np.array(
        [1000.0, 0.0, 0.0])).warnings)


def test_model_size_is_its_trimmed_faces_as_in_the_cli(tmp_path):
    """A face cut from a large surface is as large as the face: Model.bounds is info's
    bounding_box (not the control points' box), and project's scan-size warning measures the
    scan against it, word for word as `nurbsreg project` does."""
    side = lambda u0, v0, u1, v1: {"uv": {"degree": 1, "knots": [0, 0, 1, 1],
                                          "control_points": [[u0, v0], [u1, v1]]}}
    corner = {"nurbsreg_model": 1, "surfaces": [{
        "name": "corner", "degree": [1, 1], "knots_u": [0, 0, 1, 1], "knots_v": [0, 0, 1, 1],
        "control_points": [[[0, 0, 0], [0, 1000, 0]], [[1000, 0, 0], [1000, 1000, 0]]],
        "trim_loops": [{"curves": [side(0, 0, 0.01, 0), side(0.01, 0, 0, 0.01),
                                   side(0, 0.01, 0, 0)]}]}]}
    path = tmp_path / "corner.json"
    path.write_text(json.dumps(corner))
    model = nurbsreg.load_model(path)
    info = model.info()
    lo, hi = model.bounds
    assert lo.tolist() == info["bounding_box"]["min"] and hi.tolist() == info["bounding_box"]["max"]
    assert np.linalg.norm(hi - lo) == pytest.approx(10 * np.sqrt(2), rel=1e-9)
    c_lo, c_hi = model.control_point_box
    assert c_lo.tolist() == info["control_point_box"]["min"]
    assert np.linalg.norm(c_hi - c_lo) == pytest.approx(1000 * np.sqrt(2), rel=1e-9)
    # 20 times the face's size, a fifth of the surface's: the CLI warns, and so must Python.
    points = np.array([[0.0, 0, 0], [200, 200, 0], [5, 1, 0], [100, 0, 0]])
    scan = tmp_path / "scan.xyz"
    np.savetxt(scan, points)
    cli = run_cli("project", "--model", str(path), "--points", str(scan),
                  "--out", str(tmp_path / "r.csv"))
    cli_lines = [line for line in cli.stderr.splitlines() if "times the size of the model" in line]
    assert len(cli_lines) == 1, cli.stderr
    with pytest.warns(nurbsreg.NurbsregWarning) as caught:
        nurbsreg.project(model, points)
    notes = [str(w.message) for w in caught if "times the size of the model" in str(w.message)]
    assert len(notes) == 1 and "20 times" in notes[0]
    assert notes[0].split("points: ", 1)[1] in cli_lines[0]
