"""stereo_classic.datasets: every folder of ../shared/data, golden values, synthetic layouts, LiDAR."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from calib import CalibrationError, read_kitti_calib
from stereo_classic.datasets import (
    Scene,
    demo_scene,
    iter_kitti_object,
    iter_kitti_stereo,
    iter_oakd,
    iter_scenes,
    load_kitti_lidar_folder,
    load_kitti_object,
    load_kitti_stereo,
    load_middlebury2014,
    load_middlebury_classic,
    load_named_pair,
    load_oakd,
    load_scene,
    project_lidar,
    read_kitti_calib_file,
    read_velodyne,
)
from stereo_classic.io import FileFormatError, write_image, write_kitti_disparity, write_scaled_disparity


def _check_scene(s: Scene, shape: tuple[int, int]) -> None:
    assert s.left.shape == shape + (3,) and s.right.shape == shape + (3,)
    assert s.left.dtype == np.uint8 and s.right.dtype == np.uint8
    if s.gt_disparity is not None:
        gt = s.gt_disparity
        assert gt.shape == shape and gt.dtype == np.float32
        assert not np.isinf(gt).any(), "unknown must be NaN, never inf"
        assert np.nanmin(gt) > 0
    if s.nonocc_mask is not None:
        assert s.nonocc_mask.shape == shape and s.nonocc_mask.dtype == bool
        if s.gt_disparity is not None:
            assert np.isfinite(s.gt_disparity[s.nonocc_mask]).all()
    if s.rig is not None:
        assert s.rig.image_size == (shape[1], shape[0])


# ------------------------------------------------------------------------------- real data, golden values


def test_middlebury2014_motorcycle_golden(shared_data: Path) -> None:
    s = load_middlebury2014(shared_data / "middlebury2014" / "trainingQ" / "Motorcycle")
    _check_scene(s, (497, 741))
    assert s.name == "Motorcycle" and s.layout == "middlebury2014"
    assert s.rig.focal_px == pytest.approx(999.421)
    assert s.rig.baseline_m == pytest.approx(0.193001)  # 193.001 mm in the file
    assert s.rig.doffs == pytest.approx(32.778)
    assert s.max_disparity == 70  # ndisp
    gt = s.gt_disparity
    assert float(np.nanmax(gt)) == pytest.approx(62.87735, abs=1e-5)
    assert float(np.nanmin(gt)) == pytest.approx(9.177551, abs=1e-5)
    assert int(np.isnan(gt).sum()) == 7684  # the inf pixels of disp0GT.pfm
    assert s.nonocc_mask.mean() == pytest.approx(0.866, abs=0.002)
    # rows really are flipped: the bottom of the scene (floor) is nearer than the top (wall)
    assert np.nanmedian(gt[-50:]) > np.nanmedian(gt[:50])


@pytest.mark.parametrize(
    ("folder", "shape", "gt_max", "step", "max_disp"),
    [
        ("middlebury2001/tsukuba", (288, 384), 14.0, 1 / 16, 16),
        ("middlebury2001/venus", (383, 434), 19.75, 1 / 8, 32),
        ("middlebury2003/cones", (375, 450), 55.0, 1 / 4, 64),
        ("middlebury2003/teddy", (375, 450), 52.75, 1 / 4, 64),
    ],
)
def test_middlebury_classic_scales(shared_data: Path, folder: str, shape: tuple[int, int], gt_max: float, step: float, max_disp: int) -> None:
    s = load_middlebury_classic(shared_data / folder)
    _check_scene(s, shape)
    gt = s.gt_disparity
    assert float(np.nanmax(gt)) == pytest.approx(gt_max)
    known = gt[np.isfinite(gt)]
    np.testing.assert_allclose(known / step, np.round(known / step), atol=1e-4)  # values on the file's grid
    assert s.rig is None and s.max_disparity == max_disp


def test_tsukuba_scale_matches_raw_file(shared_data: Path) -> None:
    import cv2

    raw = cv2.imread(str(shared_data / "middlebury2001/tsukuba/disp3.pgm"), cv2.IMREAD_UNCHANGED)
    gt = load_scene(shared_data / "middlebury2001/tsukuba").gt_disparity
    known = raw > 0
    np.testing.assert_array_equal(np.isnan(gt), ~known)
    np.testing.assert_allclose(gt[known], raw[known] / 16.0)
    assert sorted(np.unique(gt[known]).tolist()) == [5.0, 6.0, 7.0, 8.0, 10.0, 11.0, 14.0]


def test_adirondack_named_pair(shared_data: Path) -> None:
    s = load_named_pair(shared_data / "adirondackQ")
    _check_scene(s, (497, 720))
    assert s.name == "Adirondack" and float(np.nanmax(s.gt_disparity)) == 60.0
    assert s.max_disparity == 64
    assert 0.85 < s.nonocc_mask.mean() < 0.95
    assert load_scene(shared_data / "adirondackQ").name == "Adirondack"


def test_oakd_pairs_and_rig(shared_data: Path) -> None:
    scenes = list(iter_oakd(shared_data / "oakd"))
    assert len(scenes) == 12
    names = [s.name for s in scenes]
    assert names == sorted(names) and "selfie" in names
    for s in scenes:
        _check_scene(s, (480, 640))
        assert s.gt_disparity is None and s.layout == "oakd"
        assert (s.left[..., 0] == s.left[..., 1]).all()  # grey expanded to BGR
    rig = scenes[0].rig
    assert rig.baseline_m == pytest.approx(0.075) and rig.focal_px == pytest.approx(451.0344543457031)
    assert scenes[0].max_disparity == 48  # f B / 1.0 m = 33.8 px -> 48
    by_name = load_scene(shared_data / "oakd" / "toy")
    by_file = load_scene(shared_data / "oakd" / "toy_left.png")
    np.testing.assert_array_equal(by_name.left, by_file.left)
    with pytest.raises(ValueError, match="12 scenes"):
        load_scene(shared_data / "oakd")
    with pytest.raises(FileNotFoundError, match="nothing_left"):
        load_oakd(shared_data / "oakd", "nothing")


def test_kitti_lidar_frame_golden(shared_data: Path) -> None:
    folder = shared_data / "kitti_object_pair"
    s = load_kitti_lidar_folder(folder)
    _check_scene(s, (375, 1242))
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


def test_every_shared_folder_loads(shared_data: Path) -> None:
    scenes = list(iter_scenes(shared_data))
    by_layout: dict[str, int] = {}
    for s in scenes:
        by_layout[s.layout] = by_layout.get(s.layout, 0) + 1
        _check_scene(s, s.left.shape[:2])
        assert s.max_disparity is not None and s.max_disparity > 0
    assert by_layout == {
        "named_pair": 1,
        "kitti_lidar": 1,
        "middlebury2001": 2,
        "middlebury2003": 2,
        "middlebury2014": 1,
        "oakd": 12,
    }
    # every folder holding files is covered by some scene
    covered = {s.path.resolve() for s in scenes}
    folders = {p.parent.resolve() for p in shared_data.rglob("*.png")}
    assert folders <= covered
    with pytest.raises(ValueError, match="iter_scenes"):
        load_scene(shared_data / "middlebury2014")


# ------------------------------------------------------------------------------- demo


def test_demo_scene() -> None:
    s = demo_scene()
    _check_scene(s, (500, 741))
    assert s.rig.focal_px == pytest.approx(994.978)
    assert s.rig.baseline_m == pytest.approx(0.193001)
    assert s.rig.doffs == pytest.approx(31.086)
    # principal point as documented in skimage.data.stereo_motorcycle.__doc__
    assert s.rig.cx_left == pytest.approx(311.193)
    assert s.rig.cx_right == pytest.approx(311.193 + 31.086)
    assert s.rig.cy == pytest.approx(254.877)
    from skimage import data

    rgb, _, disp = data.stereo_motorcycle()
    np.testing.assert_array_equal(s.left[..., ::-1], rgb)  # BGR
    np.testing.assert_array_equal(np.isnan(s.gt_disparity), ~np.isfinite(disp))
    assert float(np.nanmax(s.gt_disparity)) == pytest.approx(59.90896, abs=1e-4)
    depth = s.rig.depth(s.gt_disparity)
    assert 1.5 < np.nanmedian(depth) < 3.5  # a motorbike a few metres away


# ------------------------------------------------------------------------------- synthetic layouts


def _pair(rng: np.random.Generator, h: int = 20, w: int = 30) -> tuple[np.ndarray, np.ndarray]:
    return rng.integers(0, 256, (h, w, 3), dtype=np.uint8), rng.integers(0, 256, (h, w, 3), dtype=np.uint8)


def _kitti_rect_calib(path: Path, f: float = 721.5377, cx: float = 609.5593, cy: float = 172.854, tx: float = -387.5744) -> None:
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


@pytest.mark.parametrize(("width", "scale"), [(30, 3.0), (463, 3.0), (695, 2.0), (1240, 1.0), (1390, 1.0)])
def test_middlebury_2005_layout_and_scale(tmp_path: Path, width: int, scale: float) -> None:
    # 2005/2006 maps hold full-resolution disparities: third size (~450 px wide) x3, half x2, full x1
    rng = np.random.default_rng(7)
    left, right = _pair(rng, 6, width)
    write_image(tmp_path / "view1.png", left)
    write_image(tmp_path / "view5.png", right)
    raw = rng.integers(10, 240, (6, width)).astype(np.float64)
    raw[3, 3] = np.nan
    write_scaled_disparity(tmp_path / "disp1.png", raw, 1.0)
    s = load_scene(tmp_path)
    assert s.layout == "middlebury2005/2006"
    np.testing.assert_allclose(s.gt_disparity, raw / scale, rtol=1e-6)
    assert s.max_disparity == int(np.ceil(np.nanmax(raw) / scale / 16) * 16)
    s7 = load_middlebury_classic(tmp_path, disparity_scale=7)
    np.testing.assert_allclose(s7.gt_disparity, raw / 7, rtol=1e-6)


@pytest.mark.parametrize(("width", "scale"), [(450, 4.0), (900, 2.0), (1800, 1.0), (40, 4.0)])
def test_middlebury_2003_png_scale_follows_size(tmp_path: Path, width: int, scale: float) -> None:
    rng = np.random.default_rng(11)
    left, right = _pair(rng, 4, width)
    write_image(tmp_path / "im2.png", left)
    write_image(tmp_path / "im6.png", right)
    raw = rng.integers(1, 250, (4, width)).astype(np.float64)
    write_scaled_disparity(tmp_path / "disp2.png", raw, 1.0)
    s = load_middlebury_classic(tmp_path)
    assert s.layout == "middlebury2003"
    np.testing.assert_allclose(s.gt_disparity, raw / scale, rtol=1e-6)


def test_middlebury2014_without_ground_truth_or_calib(tmp_path: Path) -> None:
    left, right = _pair(np.random.default_rng(8))
    write_image(tmp_path / "im0.png", left)
    write_image(tmp_path / "im1.png", right)
    s = load_middlebury2014(tmp_path)
    assert s.gt_disparity is None and s.rig is None and s.max_disparity is None


def test_mismatched_files_are_clear_errors(tmp_path: Path) -> None:
    rng = np.random.default_rng(9)
    left, _ = _pair(rng)
    write_image(tmp_path / "im0.png", left)
    write_image(tmp_path / "im1.png", left[:10])
    with pytest.raises(FileFormatError, match="im1.png"):
        load_scene(tmp_path)
    write_image(tmp_path / "im1.png", left)
    (tmp_path / "disp0GT.pfm").write_bytes(b"Pf\n3 3\n-1.0\n" + b"\0" * 36)
    with pytest.raises(FileFormatError, match="disp0GT.pfm"):
        load_scene(tmp_path)
    (tmp_path / "disp0GT.pfm").write_bytes(b"Pf\n3 3\n-1.0\n" + b"\0" * 10)
    with pytest.raises(FileFormatError, match="truncated"):
        load_scene(tmp_path)
    with pytest.raises(FileFormatError, match="truncated"):
        list(iter_scenes(tmp_path))
    with pytest.warns(UserWarning, match="disp0GT.pfm"):
        assert list(iter_scenes(tmp_path, skip_errors=True)) == []


def test_load_scene_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="nowhere"):
        load_scene(tmp_path / "nowhere")
    with pytest.raises(FileFormatError, match="no supported stereo layout"):
        load_scene(tmp_path)
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        load_scene(tmp_path / "notes.txt")
    with pytest.raises(TypeError, match="path"):
        load_scene(3)  # type: ignore[arg-type]
    with pytest.raises(NotADirectoryError):
        load_middlebury2014(tmp_path / "notes.txt")
    assert list(iter_scenes(tmp_path)) == []


def test_named_pair_needs_a_name_when_ambiguous(tmp_path: Path) -> None:
    rng = np.random.default_rng(10)
    for name in ("a", "b"):
        left, right = _pair(rng)
        write_image(tmp_path / f"{name}_left.png", left)
        write_image(tmp_path / f"{name}_right.png", right)
    with pytest.raises(ValueError, match="`name`"):
        load_named_pair(tmp_path)
    assert load_named_pair(tmp_path, "b").gt_disparity is None
    assert [s.name for s in iter_scenes(tmp_path)] == ["a", "b"]
    (tmp_path / "stereodemo_calibration.json").write_text(
        json.dumps({"width": 30, "height": 20, "baseline_meters": 0.1, "fx": 50.0, "fy": 50.0, "cx0": 15.0, "cx1": 15.0, "cy": 10.0})
    )
    s = load_scene(tmp_path / "a")
    assert s.layout == "oakd" and s.max_disparity is None and s.rig.baseline_m == pytest.approx(0.1)


def test_scene_checks_itself() -> None:
    img = np.zeros((4, 5, 3), np.uint8)
    Scene("ok", img, img, gt_disparity=np.full((4, 5), np.nan, np.float32), max_disparity=np.int64(16))
    with pytest.raises(ValueError, match="same shape"):
        Scene("x", img, img[:3])
    with pytest.raises(ValueError, match="gt_disparity"):
        Scene("x", img, img, gt_disparity=np.zeros((4, 5)))
    with pytest.raises(ValueError, match="NaN"):
        Scene("x", img, img, gt_disparity=np.full((4, 5), np.inf, np.float32))
    with pytest.raises(ValueError, match="nonocc_mask"):
        Scene("x", img, img, nonocc_mask=np.zeros((4, 5), np.uint8))
    with pytest.raises(ValueError, match="max_disparity"):
        Scene("x", img, img, max_disparity=0)
    with pytest.raises(TypeError, match="max_disparity"):
        Scene("x", img, img, max_disparity=16.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="lidar_points"):
        Scene("x", img, img, lidar_points=np.zeros((3, 2), np.float32))
    with pytest.raises(ValueError, match="left"):
        Scene("x", img.astype(np.float32), img)


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


# ------------------------------------------------------------------------------- one parser per format


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


def _middlebury_folder(d: Path, ndisp: str) -> None:
    left, right = _pair(np.random.default_rng(11))
    write_image(d / "im0.png", left)
    write_image(d / "im1.png", right)
    (d / "calib.txt").write_text(
        "cam0=[50 0 15; 0 50 10; 0 0 1]\ncam1=[50 0 17; 0 50 10; 0 0 1]\ndoffs=2\nbaseline=100\n"
        f"width=30\nheight=20\nndisp={ndisp}\n"
    )


def test_middlebury_ndisp_read_by_calib(tmp_path: Path) -> None:
    _middlebury_folder(tmp_path, "48")
    assert load_middlebury2014(tmp_path).max_disparity == 48
    _middlebury_folder(tmp_path, "47.5")  # was truncated to 47 silently
    with pytest.raises(FileFormatError, match="ndisp must be a whole number"):
        load_middlebury2014(tmp_path)
    (tmp_path / "calib.txt").write_text((tmp_path / "calib.txt").read_text() + "garbage line\n")
    with pytest.raises(CalibrationError, match="is not `key=value`"):
        load_middlebury2014(tmp_path)


@pytest.mark.parametrize("depth_range", [[0, 5], [2.0, 1.0], ["1", 5], [1.0], "near"])
def test_oakd_bad_depth_range_is_an_error(tmp_path: Path, depth_range: object) -> None:
    left, right = _pair(np.random.default_rng(12))
    write_image(tmp_path / "a_left.png", left)
    write_image(tmp_path / "a_right.png", right)
    calib = {"width": 30, "height": 20, "baseline_meters": 0.1, "fx": 50.0, "cx0": 15.0, "cx1": 15.0, "cy": 10.0}
    path = tmp_path / "stereodemo_calibration.json"
    path.write_text(json.dumps({**calib, "depth_range": [0.25, 5.0]}))
    assert load_oakd(tmp_path, "a").max_disparity == 32  # 50 * 0.1 / 0.25 = 20 px -> 32
    path.write_text(json.dumps({**calib, "depth_range": depth_range}))  # was silently ignored
    with pytest.raises(CalibrationError, match="`depth_range`"):
        load_oakd(tmp_path, "a")
