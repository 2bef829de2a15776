"""stereo_classic.datasets.kitti: stereo 2012/2015 layouts, object frames with LiDAR, projection, calibration."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib import CalibrationError, read_kitti_calib
from stereo_classic.datasets import (
    iter_kitti_object,
    iter_kitti_stereo,
    iter_scenes,
    load_kitti_lidar_folder,
    load_kitti_object,
    load_kitti_stereo,
    load_scene,
    project_lidar,
    read_kitti_calib_file,
    read_velodyne,
)
from stereo_classic.io import FileFormatError, write_image, write_kitti_disparity


def _pair(rng: np.random.Generator, h: int = 20, w: int = 30) -> tuple[np.ndarray, np.ndarray]:
    return rng.integers(0, 256, (h, w, 3), dtype=np.uint8), rng.integers(0, 256, (h, w, 3), dtype=np.uint8)


def test_kitti_lidar_frame_golden(shared_data: Path, check_scene: Callable[..., None]) -> None:
    folder = shared_data / "kitti_object_pair"
    s = load_kitti_lidar_folder(folder)
    check_scene(s, (375, 1242))
    assert s.rig.focal_px == pytest.approx(721.5377)
    assert s.rig.baseline_m == pytest.approx(0.5327, abs=5e-4)
    depth = s.gt_depth
    assert depth.dtype == np.float32 and depth.shape == (375, 1242)
    assert int(np.isfinite(depth).sum()) == 17781
    assert s.lidar_points.shape == (17816, 3) and s.lidar_points.dtype == np.float32
    assert np.nanmin(depth) > 0.1 and np.nanmax(depth) < 120
    # the points are in the left camera frame: they project back onto their pixels with the rig
    pts = s.lidar_points
    u = s.rig.focal_px * pts[:, 0] / pts[:, 2] + s.rig.cx_left
    v = s.rig.focal_px * pts[:, 1] / pts[:, 2] + s.rig.cy
    ui, vi = np.floor(u + 0.5).astype(int), np.floor(v + 0.5).astype(int)
    assert ((ui >= 0) & (ui < 1242) & (vi >= 0) & (vi < 375)).all()
    # the nearest point of each pixel is kept (float32 points: a rare u of exactly x.5 may round away)
    assert np.mean(depth[vi, ui] <= pts[:, 2] + 1e-4) > 0.999
    # depth -> disparity -> depth through the rig
    disp = s.rig.disparity(depth)
    assert np.isfinite(disp).sum() == 17781
    np.testing.assert_allclose(s.rig.depth(disp)[np.isfinite(depth)], depth[np.isfinite(depth)], rtol=1e-5)
    assert s.max_disparity >= np.nanmax(disp)


def test_kitti_lidar_projection_matches_reference(shared_data: Path) -> None:
    folder = shared_data / "kitti_object_pair"
    ref = np.load(folder / "lidar_depth_left.npy")  # 0 = no point, truncated pixel coordinates
    calib = read_kitti_calib_file(folder / "calib.txt")
    depth, pts = project_lidar(
        read_velodyne(folder / "lidar.bin"),
        P=calib["P2"].reshape(3, 4),
        R0_rect=calib["R0_rect"].reshape(3, 3),
        Tr_velo_to_cam=calib["Tr_velo_to_cam"].reshape(3, 4),
        image_size=(1242, 375),
        pixel_rounding="floor",
    )
    assert int((ref > 0).sum()) == 17800
    np.testing.assert_array_equal(np.isfinite(depth), ref > 0)
    # same pixels, same depth up to camera 2's 2.7 mm offset along Z (P2[2, 3]) that the reference ignores
    diff = depth[ref > 0] - ref[ref > 0]
    assert np.abs(diff - 0.002745884).max() < 1e-4
    assert pts.shape == (17835, 3)


def test_velodyne_reader_counts(shared_data: Path, tmp_path: Path) -> None:
    pts = read_velodyne(shared_data / "kitti_object_pair" / "lidar.bin")
    assert pts.shape == (103344, 4) and pts.dtype == np.float32
    (tmp_path / "bad.bin").write_bytes(b"\0" * 20)
    with pytest.raises(FileFormatError, match="multiple of 16"):
        read_velodyne(tmp_path / "bad.bin")
    with pytest.raises(FileNotFoundError):
        read_velodyne(tmp_path / "none.bin")


def _kitti_rect_calib(path: Path, f: float = 721.5377, cx: float = 14.5, cy: float = 9.5, tx: float = -387.5744) -> None:
    # KITTI's focal length and baseline on 30x20 images: the principal point must be inside them (calib checks)
    p2 = f"{f} 0 {cx} 0 0 {f} {cy} 0 0 0 1 0"
    p3 = f"{f} 0 {cx} {tx} 0 {f} {cy} 0 0 0 1 0"
    path.write_text(f"calib_time: 09-Jan-2012 13:57:47\nS_rect_02: 30 20\nP_rect_02: {p2}\nP_rect_03: {p3}\n")


@pytest.mark.parametrize("year", [2012, 2015])
def test_kitti_stereo_layout(tmp_path: Path, year: int) -> None:
    rng = np.random.default_rng(6)
    t = tmp_path / "training"
    dirs = ("image_2", "image_3", "disp_occ_0", "disp_noc_0") if year == 2015 else ("colored_0", "colored_1", "disp_occ", "disp_noc")
    for d in dirs:
        (t / d).mkdir(parents=True)
    truth = {}
    for fid in ("000000", "000001"):
        left, right = _pair(rng)
        write_image(t / dirs[0] / f"{fid}_10.png", left)
        write_image(t / dirs[1] / f"{fid}_10.png", right)
        write_image(t / dirs[0] / f"{fid}_11.png", left)  # next frame (flow): not a stereo scene
        occ = rng.uniform(1, 100, (20, 30))
        occ[0, :5] = np.nan
        noc = occ.copy()
        noc[5, :] = np.nan
        write_kitti_disparity(t / dirs[2] / f"{fid}_10.png", occ)
        write_kitti_disparity(t / dirs[3] / f"{fid}_10.png", noc)
        truth[fid] = (left, occ, noc)
    calib_dir = t / ("calib_cam_to_cam" if year == 2015 else "calib")
    calib_dir.mkdir()
    for fid in truth:
        _kitti_rect_calib(calib_dir / f"{fid}.txt")
    s = load_kitti_stereo(tmp_path, 1)
    left, occ, noc = truth["000001"]
    assert s.name == "000001_10" and s.layout == "kitti_stereo"
    np.testing.assert_array_equal(s.left, left)
    np.testing.assert_allclose(s.gt_disparity, occ, atol=1 / 512)
    np.testing.assert_array_equal(s.nonocc_mask, np.isfinite(noc))
    assert s.rig.baseline_m == pytest.approx(387.5744 / 721.5377, rel=1e-6)
    assert s.max_disparity == 112  # largest ground truth (< 100 px) rounded up to 16
    assert load_kitti_stereo(t, "000001_10").name == "000001_10"
    assert [x.name for x in iter_kitti_stereo(tmp_path)] == ["000000_10", "000001_10"]
    assert [x.name for x in iter_scenes(tmp_path)] == ["000000_10", "000001_10"]
    with pytest.raises(ValueError, match="2 scenes"):
        load_scene(t)
    with pytest.raises(FileNotFoundError, match="000009_10"):
        load_kitti_stereo(t, 9)
    with pytest.raises(ValueError, match="frame"):
        load_kitti_stereo(t, "../x")
    with pytest.raises(ValueError, match="frame"):
        load_kitti_stereo(t, -1)


def test_kitti_object_layout_equals_single_folder(shared_data: Path, tmp_path: Path) -> None:
    src = shared_data / "kitti_object_pair"
    t = tmp_path / "object" / "training"
    for d in ("image_2", "image_3", "calib", "velodyne"):
        (t / d).mkdir(parents=True)
    shutil.copy(src / "left.png", t / "image_2" / "000007.png")
    shutil.copy(src / "right.png", t / "image_3" / "000007.png")
    shutil.copy(src / "calib.txt", t / "calib" / "000007.txt")
    shutil.copy(src / "lidar.bin", t / "velodyne" / "000007.bin")
    a = load_kitti_object(tmp_path / "object", 7)
    b = load_kitti_lidar_folder(src)
    assert a.name == "000007" and a.layout == "kitti_object"
    np.testing.assert_array_equal(a.gt_depth, b.gt_depth)
    np.testing.assert_array_equal(a.lidar_points, b.lidar_points)
    assert [s.name for s in iter_kitti_object(t)] == ["000007"]
    assert [s.name for s in iter_scenes(tmp_path)] == ["000007"]


def test_project_lidar_synthetic_and_errors() -> None:
    f, cx, cy = 100.0, 50.0, 40.0
    P = np.array([[f, 0, cx, 0], [0, f, cy, 0], [0, 0, 1, 0]])
    # identity velo->cam: points given directly in camera coordinates
    Tr = np.hstack([np.eye(3), np.zeros((3, 1))])
    pts = np.array([[0.0, 0.0, 10.0], [0.0, 0.0, 5.0], [0.5, -0.4, 2.0], [0.0, 0.0, -3.0], [100.0, 0, 1.0]])
    depth, cam = project_lidar(pts, P=P, R0_rect=np.eye(3), Tr_velo_to_cam=Tr, image_size=(100, 80))
    assert np.isfinite(depth).sum() == 2  # behind the camera and outside the image: dropped
    assert depth[40, 50] == 5.0  # nearest of the two points on the principal point
    assert depth[20, 75] == 2.0  # u = 100 * 0.5 / 2 + 50, v = 100 * -0.4 / 2 + 40
    np.testing.assert_allclose(cam, pts[:3], atol=1e-6)
    for kwargs, match in (
        ({"P": np.eye(3)}, "`P`"),
        ({"R0_rect": np.eye(4)}, "R0_rect"),
        ({"image_size": (0, 5)}, "image_size"),
        ({"pixel_rounding": "ceil"}, "pixel_rounding"),
        ({"min_depth": float("nan")}, "min_depth"),
    ):
        args = {"P": P, "R0_rect": np.eye(3), "Tr_velo_to_cam": Tr, "image_size": (100, 80)} | kwargs
        with pytest.raises(ValueError, match=match):
            project_lidar(pts, **args)
    with pytest.raises(ValueError, match="points"):
        project_lidar(np.zeros((3, 2)), P=P, R0_rect=np.eye(3), Tr_velo_to_cam=Tr, image_size=(100, 80))


@settings(max_examples=180, deadline=None)
@given(
    xyz=st.lists(st.tuples(*(st.one_of(st.floats(-50, 50), st.just(float("nan"))) for _ in range(3))), max_size=40),
    size=st.tuples(st.integers(1, 40), st.integers(1, 40)),
)
def test_project_lidar_property(xyz: list[tuple[float, float, float]], size: tuple[int, int]) -> None:
    P = np.array([[30.0, 0, size[0] / 2, 1.0], [0, 30.0, size[1] / 2, 0], [0, 0, 1, 0]])
    Tr = np.hstack([np.eye(3), np.zeros((3, 1))])
    pts = np.array(xyz, dtype=np.float64).reshape(-1, 3)
    depth, cam = project_lidar(pts, P=P, R0_rect=np.eye(3), Tr_velo_to_cam=Tr, image_size=size)
    assert depth.shape == (size[1], size[0]) and depth.dtype == np.float32
    assert not np.isinf(depth).any()
    assert np.isfinite(depth).sum() <= len(cam) <= len(pts)
    if np.isfinite(depth).any():
        assert np.nanmin(depth) > 0.1
        assert np.isin(depth[np.isfinite(depth)], cam[:, 2]).all()


def test_kitti_calib_file_is_calibs_strict_parser(tmp_path: Path) -> None:
    path = tmp_path / "calib.txt"
    _kitti_rect_calib(path)
    assert read_kitti_calib_file(path).keys() == read_kitti_calib(path).keys()
    assert read_kitti_calib_file(path)["calib_time"] is None
    path.write_text(path.read_text() + "P_rect_02 721 0 609\n")  # a line without `key:` is an error, not skipped
    with pytest.raises(CalibrationError, match="line 5 is not `key: values`"):
        read_kitti_calib_file(path)
    with pytest.raises(FileNotFoundError, match="missing.txt"):
        read_kitti_calib_file(tmp_path / "missing.txt")
