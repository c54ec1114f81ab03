"""Point-cloud files, models and synthetic scans from Python: the CLI's readers, writers and
error messages."""

import numpy as np
import pytest

import nurbsreg
from conftest import PANEL, SHARED, read_pose_file, run_cli


@pytest.fixture(scope="module")
def points():
    return np.random.default_rng(2).normal(size=(257, 3)) * [10, 20, 3]


@pytest.mark.parametrize("name, kwargs", [
    ("c.pcd", {"double_precision": True}),
    ("c.pcd", {"double_precision": True, "encoding": "ascii"}),
    ("c.pcd", {"double_precision": True, "encoding": "binary_compressed"}),
    ("c.ply", {"double_precision": True}),
    ("c.xyz", {"double_precision": True}),
    ("c.csv", {"double_precision": True}),
])
def test_round_trip(points, tmp_path, name, kwargs):
    nurbsreg.write_point_cloud(tmp_path / name, points, **kwargs)
    cloud = nurbsreg.read_point_cloud(tmp_path / name)
    np.testing.assert_array_equal(cloud.points, points)
    np.testing.assert_array_equal(cloud.index, np.arange(len(points)))
    assert (cloud.skipped, cloud.total) == (0, len(points))


def test_float32_files_and_nan_rows(points, tmp_path):
    holes = points.copy()
    holes[[1, 5]] = np.nan
    nurbsreg.write_point_cloud(tmp_path / "h.pcd", np.asfortranarray(holes))
    cloud = nurbsreg.read_point_cloud(tmp_path / "h.pcd")
    keep = np.ones(len(points), bool)
    keep[[1, 5]] = False
    assert (cloud.skipped, cloud.total, cloud.width, cloud.height) == (2, 257, 257, 1)
    np.testing.assert_array_equal(cloud.index, np.flatnonzero(keep))
    np.testing.assert_array_equal(cloud.points, points[keep].astype(np.float32))


def cli_error(*args):
    done = run_cli(*args, check=False)
    assert done.returncode == 3
    line = done.stderr.strip().splitlines()[-1]
    assert line.startswith("error: ")
    return line[len("error: "):]


def test_bad_files_raise_input_error_with_the_cli_message(tmp_path):
    bad = tmp_path / "bad.xyz"
    bad.write_text("1 2 3\n4 5\n")
    with pytest.raises(nurbsreg.InputError) as caught:
        nurbsreg.read_point_cloud(bad)
    assert isinstance(caught.value, ValueError)
    assert str(caught.value) == cli_error("project", "--model", PANEL, "--points", bad, "--out",
                                          tmp_path / "r.csv")
    broken = tmp_path / "broken.json"
    broken.write_text('{"nurbsreg_model": 1, "surfaces": [{"name": "s", "degree": [3, 3]}]}')
    with pytest.raises(nurbsreg.InputError) as caught:
        nurbsreg.load_model(broken)
    assert str(caught.value) == cli_error("info", "--model", broken)
    with pytest.raises(nurbsreg.InputError, match="missing.pcd"):
        nurbsreg.read_point_cloud(tmp_path / "missing.pcd")


def test_unwritable_output_raises_output_error(points, tmp_path):
    with pytest.raises(nurbsreg.OutputError) as caught:
        nurbsreg.write_point_cloud(tmp_path / "no" / "such" / "dir.pcd", points)
    assert isinstance(caught.value, OSError) and "dir.pcd" in str(caught.value)
    with pytest.raises(nurbsreg.OutputError, match="c.obj"):
        nurbsreg.write_point_cloud(tmp_path / "c.obj", points)
    with pytest.raises(ValueError, match="encoding"):
        nurbsreg.write_point_cloud(tmp_path / "c.pcd", points, encoding="zip")


def test_model_info_is_the_cli_info(panel):
    info = panel.info()
    assert panel.units == info["units"] == "mm"
    assert info["bezier_patches"] == panel.patch_count == 49
    assert len(info["surfaces"]) == panel.surface_count == 1
    assert info["skipped_faces"] == []
    lo, hi = panel.bounds
    assert lo.shape == (3,) and (hi > lo).all()
    import json
    assert info == json.loads(run_cli("info", "--model", PANEL, "--json").stdout)


def test_step_model_loads(tmp_path):
    step = SHARED / "data" / "real" / "occt" / "screw.step"
    if not step.exists():
        pytest.skip(f"{step} not found")
    model = nurbsreg.load_model(step)
    assert model.surface_count > 0 and model.units == "mm"


def test_synth_is_the_cli_synth(panel, tmp_path):
    args = dict(noise=0.05, pose=(3, -2, 4, 3, -2, 2), seed=9, outliers=0.01,
                view_fraction=0.7, view_direction=(0, 1, 1), fixture=0.01, fixture_up=(0, 1, 0))
    scan = nurbsreg.synth(panel, 3000, **args)
    run_cli("synth", "--model", PANEL, "--points", 3000, "--noise", 0.05, "--pose",
            "3 -2 4 3 -2 2", "--seed", 9, "--outliers", 0.01, "--view-fraction", 0.7,
            "--view-direction", "0 1 1", "--fixture", 0.01, "--fixture-up", "0 1 0",
            "--out", tmp_path / "s.xyz", "--out-pose", tmp_path / "pose.txt")
    # The CLI writes float32 coordinates (shortest text of each float).
    cli_points = nurbsreg.read_point_cloud(tmp_path / "s.xyz").points
    np.testing.assert_array_equal(scan.points.astype(np.float32), cli_points.astype(np.float32))
    np.testing.assert_array_equal(scan.T_model_scan, read_pose_file(tmp_path / "pose.txt"))
    assert scan.on_model.dtype == bool and (~scan.on_model).sum() == 60
    assert scan.uv.shape == (len(scan.points), 2) and scan.surface.dtype == np.int32
    with pytest.raises(ValueError, match="pose: expected 6 numbers"):
        nurbsreg.synth(panel, 10, pose=(1, 2, 3))
    with pytest.raises(ValueError, match="points: must be > 0"):
        nurbsreg.synth(panel, 0)
    with pytest.raises(ValueError, match="outliers and fixture"):
        nurbsreg.synth(panel, 10, outliers=0.6, fixture=0.5)


def test_a_face_beyond_its_surface_warns_as_the_cli(tmp_path):
    def side(u0, v0, u1, v1):
        return {"uv": {"degree": 1, "knots": [0, 0, 1, 1], "control_points": [[u0, v0], [u1, v1]]}}
    import json
    plate = {"nurbsreg_model": 1, "surfaces": [{
        "name": "plate", "degree": [1, 1], "knots_u": [0, 0, 1, 1], "knots_v": [0, 0, 1, 1],
        "control_points": [[[0, 0, 0], [0, 10, 0]], [[10, 0, 0], [10, 10, 0]]],
        "trim_loops": [{"curves": [side(0.5, 0.2, 1.5, 0.2), side(1.5, 0.2, 1.5, 0.8),
                                   side(1.5, 0.8, 0.5, 0.8), side(0.5, 0.8, 0.5, 0.2)]}]}]}
    path = tmp_path / "plate.json"
    path.write_text(json.dumps(plate))
    with pytest.warns(nurbsreg.NurbsregWarning) as caught:
        nurbsreg.load_model(path)
    message = str(caught[0].message)
    assert ("the trim loops of 1 faces leave their surface's parameter domain (plate by 50%"
            in message)
    assert message in run_cli("info", "--model", path).stderr
