"""nurbsreg.inspect: the `nurbsreg inspect` command's numbers and files, from Python."""

import json

import numpy as np
import pytest

import nurbsreg
from conftest import PANEL, run_cli, without_times


@pytest.fixture(scope="module")
def holey_scan(panel, tmp_path_factory):
    """A scan file with NaN rows (the file positions of the others are what `index` says)."""
    d = tmp_path_factory.mktemp("inspect")
    synthetic = nurbsreg.synth(panel, 8000, noise=0.02, seed=4, pose=(2, -1, 3, 2, -1, 1))
    points = synthetic.points.copy()
    points[[10, 4000]] = np.nan
    nurbsreg.write_point_cloud(d / "scan.pcd", points, double_precision=True)
    return d / "scan.pcd", points


@pytest.fixture(scope="module")
def cli_inspection(holey_scan, tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "out"
    run_cli("inspect", "--model", PANEL, "--scan", holey_scan[0], "--tolerance", 0.05,
            "--out-dir", out)
    return out


def test_out_dir_is_the_clis_inspection(panel, holey_scan, cli_inspection, tmp_path):
    r = nurbsreg.inspect(panel, str(holey_scan[0]), tolerance=0.05, out_dir=tmp_path / "py")
    expected = json.loads((cli_inspection / "inspect.json").read_text())
    mine = json.loads((tmp_path / "py" / "inspect.json").read_text())
    assert without_times(mine) == without_times(expected)
    assert without_times(r.report()) == without_times(expected)
    # The coloured cloud and the per-face table byte for byte; the page and picture exist.
    for name in ("deviations.ply", "inspect_faces.csv"):
        assert (tmp_path / "py" / name).read_bytes() == (cli_inspection / name).read_bytes()
    assert (tmp_path / "py" / "report.html").stat().st_size > 10000
    assert (tmp_path / "py" / "deviations.png").read_bytes()[:4] == b"\x89PNG"
    assert r.faces_csv() == (cli_inspection / "inspect_faces.csv").read_text()


def test_arrays_summary_and_single_files(panel, holey_scan, cli_inspection, tmp_path):
    scan_file, points = holey_scan
    expected = json.loads((cli_inspection / "inspect.json").read_text())
    r = nurbsreg.inspect(panel, points, tolerance=0.05, ply=tmp_path / "cloud.ply")
    assert len(r) == 7998 and r.skipped == 2 and r.unprojected == 0
    # Rows of the input array: the NaN rows are left out, the others keep their positions.
    np.testing.assert_array_equal(r.index, np.delete(np.arange(8000), [10, 4000]))
    assert (tmp_path / "cloud.ply").read_bytes() == (cli_inspection / "deviations.ply").read_bytes()
    assert not (tmp_path / "report.html").exists()
    mine = without_times(r.report())
    assert mine.pop("scan") == "" and without_times(expected).pop("scan")
    reference = without_times(expected)
    reference.pop("scan")
    assert mine == reference
    for field in ("mean", "std", "rms", "min", "max", "p5", "p95", "inside", "below", "above",
                  "inside_tolerance"):
        assert r.summary[field] == expected[field], field
    assert r.summary["points"] == 7998 and r.passed == (expected["verdict"] == "pass")
    assert r.tolerance == (-0.05, 0.05) and len(r.faces) == 1 and r.faces[0]["points"] == 7998
    # The per-point deviations are the exact signed distances of the aligned points.
    np.testing.assert_allclose(r.points, np.delete(points, [10, 4000], axis=0)
                               @ r.alignment.T_model_scan[:3, :3].T
                               + r.alignment.T_model_scan[:3, 3], rtol=0, atol=1e-12)
    exact = nurbsreg.project(panel, r.points)
    np.testing.assert_allclose(r.signed_distance, exact.signed_distance, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(r.face, exact.entity)
    # The page and the picture alone.
    nurbsreg.inspect(panel, points, tolerance=0.05, html=tmp_path / "r.html",
                     png=tmp_path / "p.png", viewer_points=1000)
    assert b"<html" in (tmp_path / "r.html").read_bytes()[:2000].lower()
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"


def test_float32_strided_scan_inspects_as_float64(panel, holey_scan):
    _, points = holey_scan
    single = points.astype(np.float32)
    reference = nurbsreg.inspect(panel, single.astype(np.float64), tolerance=0.05)
    strided = np.asfortranarray(single)[::1]
    r = nurbsreg.inspect(panel, strided, tolerance=0.05)
    np.testing.assert_array_equal(r.signed_distance, reference.signed_distance)
    assert r.summary == reference.summary and r.skipped == 2


def test_given_pose_and_asymmetric_band_as_the_cli(panel, holey_scan, cli_inspection, tmp_path):
    scan_file, _ = holey_scan
    T = np.array(json.loads((cli_inspection / "inspect.json").read_text())["pose"])
    (tmp_path / "pose.txt").write_text(
        "\n".join(" ".join(repr(float(x)) for x in row) for row in T) + "\n")
    options = ("--tolerance-upper", 0.04, "--tolerance-lower", -0.03, "--colour-scale",
               "blue-red", "--min-inside", 0.9)
    run_cli("inspect", "--model", PANEL, "--scan", scan_file, "--pose", tmp_path / "pose.txt",
            "--out-dir", tmp_path / "cli", *options)
    r = nurbsreg.inspect(panel, str(scan_file), pose=T, tolerance_upper=0.04,
                         tolerance_lower=-0.03, colour_scale="blue-red", min_inside=0.9,
                         ply=tmp_path / "py.ply")
    expected = json.loads((tmp_path / "cli" / "inspect.json").read_text())
    assert without_times(r.report()) == without_times(expected)
    assert r.alignment is None and expected["pose_given"]
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli" / "deviations.ply").read_bytes()


def test_clutter_is_excluded_on_request_as_the_cli(panel, holey_scan, cli_inspection, tmp_path):
    """exclude_beyond= is --exclude-beyond: the same files; far points counted in ``excluded``
    and left out of every number; without it, a warning names the option."""
    scan_file, points = holey_scan
    T = np.array(json.loads((cli_inspection / "inspect.json").read_text())["pose"])
    cluttered = np.vstack([points, (T[:3, :3].T @ (np.array([[0.0, 0.0, 40.0]]).T
                                                    - T[:3, 3:4])).T.repeat(300, axis=0)])
    nurbsreg.write_point_cloud(tmp_path / "cluttered.pcd", cluttered, double_precision=True)
    (tmp_path / "pose.txt").write_text(
        "\n".join(" ".join(repr(float(x)) for x in row) for row in T) + "\n")
    run_cli("inspect", "--model", PANEL, "--scan", tmp_path / "cluttered.pcd", "--pose",
            tmp_path / "pose.txt", "--tolerance", 0.05, "--exclude-beyond", 2,
            "--out-dir", tmp_path / "cli")
    r = nurbsreg.inspect(panel, str(tmp_path / "cluttered.pcd"), pose=T, tolerance=0.05,
                         exclude_beyond=2, ply=tmp_path / "py.ply")
    expected = json.loads((tmp_path / "cli" / "inspect.json").read_text())
    assert without_times(r.report()) == without_times(expected)
    assert r.excluded == 300 and expected["excluded_points"] == 300
    assert len(r) == 7998 and expected["exclude_beyond"] == 2
    assert (tmp_path / "py.ply").read_bytes() == (tmp_path / "cli" / "deviations.ply").read_bytes()
    with pytest.warns(nurbsreg.NurbsregWarning, match="exclude_beyond=0.5"):
        plain = nurbsreg.inspect(panel, cluttered, pose=T, tolerance=0.05)
    assert plain.excluded == 0 and len(plain) == 8298
    with pytest.raises(ValueError, match="exclude_beyond: must be a distance beyond"):
        nurbsreg.inspect(panel, points, pose=T, tolerance=0.05, exclude_beyond=0.05)


def test_errors(panel, holey_scan, tmp_path):
    _, points = holey_scan
    with pytest.raises(ValueError, match="tolerance is required"):
        nurbsreg.inspect(panel, points)
    with pytest.raises(ValueError, match="tolerance: must be a positive number"):
        nurbsreg.inspect(panel, points, tolerance=-1)
    with pytest.raises(ValueError, match="tolerance_lower: must be finite"):
        nurbsreg.inspect(panel, points, tolerance_upper=0.1, tolerance_lower=float("nan"))
    with pytest.raises(ValueError, match="init and pose exclude each other"):
        nurbsreg.inspect(panel, points, tolerance=0.1, init=np.eye(4), pose=np.eye(4))
    with pytest.raises(ValueError, match="out_dir: "):
        nurbsreg.inspect(panel, points, tolerance=0.1, out_dir=tmp_path / "missing" / "out")
    with pytest.raises(ValueError, match="colour_scale"):
        nurbsreg.inspect(panel, points, tolerance=0.1, colour_scale="rainbow")
    with pytest.raises(ValueError, match="scan: no finite points to align"):
        nurbsreg.inspect(panel, np.full((4, 3), np.nan), tolerance=0.1)
    with pytest.raises(ValueError, match="scan: no finite points to align"):
        nurbsreg.inspect(panel, np.zeros((0, 3)), tolerance=0.1)
    with pytest.raises(ValueError, match="scan: no finite points to inspect"):
        nurbsreg.inspect(panel, np.zeros((0, 3), np.float32), tolerance=0.1, pose=np.eye(4))
    # A poor fit is the CLI's exit 1: nothing is written.
    with pytest.raises(nurbsreg.PoorFitError) as caught:
        nurbsreg.inspect(panel, points, tolerance=0.1, min_inlier_fraction=1.0,
                         out_dir=tmp_path / "poor")
    assert caught.value.result.fit.fit == "poor" and not (tmp_path / "poor").exists()
