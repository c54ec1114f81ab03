"""Open3D interop: an open3d.geometry.PointCloud -> numpy -> align -> the pose applied back with
Open3D lands the cloud on the model."""

import numpy as np
import pytest

import nurbsreg

o3d = pytest.importorskip("open3d")


def test_open3d_cloud_round_trip(panel):
    scan = nurbsreg.synth(panel, 5000, noise=0.01, pose=(2, 1, -3, 1.5, -2, 0.5), seed=4)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(scan.points))
    points = np.asarray(cloud.points)  # a view of Open3D's own buffer: float64, (N, 3)
    a = nurbsreg.align(panel, points)
    # A smooth panel constrains in-plane sliding weakly: within 0.02 mm of the true pose.
    np.testing.assert_allclose(a.T_model_scan, scan.T_model_scan, atol=2e-2)
    cloud.transform(a.T_model_scan)
    moved = np.asarray(cloud.points)
    np.testing.assert_allclose(moved, a.aligned, rtol=0, atol=1e-9)
    d = nurbsreg.project(panel, moved).distance
    assert np.sqrt(np.mean(d ** 2)) < 0.02  # the noise (0.01) plus nothing


def test_open3d_float32_and_files(panel, tmp_path):
    scan = nurbsreg.synth(panel, 2000, seed=8)
    path = tmp_path / "scan.pcd"
    nurbsreg.write_point_cloud(path, scan.points)
    read = o3d.io.read_point_cloud(str(path))  # Open3D reads nurbsreg's binary PCD
    np.testing.assert_allclose(np.asarray(read.points), scan.points, rtol=1e-6, atol=1e-4)
    o3d.io.write_point_cloud(str(tmp_path / "o3d.ply"), read)
    mine = nurbsreg.read_point_cloud(tmp_path / "o3d.ply")  # and Open3D's PLY
    np.testing.assert_array_equal(mine.points, np.asarray(read.points))
    r = nurbsreg.project(panel, np.asarray(read.points).astype(np.float32))
    assert (r.status == nurbsreg.STATUS_OK).all() and r.distance.max() < 1e-4


def test_open3d_reads_binary_compressed(tmp_path):
    # nurbsreg's own LZF encoder (io/src/lzf.cpp) against Open3D's decoder: long runs of equal
    # values (back references of the longest length), repeats farther back than LZF reaches,
    # and noise that does not compress.
    rng = np.random.default_rng(3)
    walk = np.cumsum(rng.normal(size=(30000, 3)), axis=0)
    points = np.concatenate([np.zeros((5000, 3)), walk, walk[:3000], rng.normal(size=(3000, 3))])
    path = tmp_path / "c.pcd"
    nurbsreg.write_point_cloud(path, points, encoding="binary_compressed")
    assert b"DATA binary_compressed" in path.read_bytes()[:400]
    read = np.asarray(o3d.io.read_point_cloud(str(path)).points)
    np.testing.assert_array_equal(read, points.astype(np.float32).astype(np.float64))
