"""stereo_classic.datasets.drivingstereo: the shared frames, golden rig, disparity x depth = f B, hostile folders."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from calib import CalibrationError
from stereo_classic.datasets import Scene, iter_drivingstereo, iter_scenes, load_drivingstereo, load_scene
from stereo_classic.io import FileFormatError, write_image, write_kitti_depth, write_kitti_disparity

SEQ = "2018-07-09-16-11-56"
FIRST = f"{SEQ}_{SEQ}-502"  # first frame of the shared sequence, sorted by time

_ROW2_3 = "0.000000e+0 5.000000e+1 1.000000e+1 0.000000e+0 0.000000e+0 0.000000e+0 1.000000e+0 0.000000e+0"
#: Calibration in the dataset's own layout for a 30 x 20 image (half-size style: P_rect_103's tx is the
#: full-resolution value, twice what the baseline gives, as in the real files).
CALIB = (
    "calib_time: 20180703\n"
    "S_rect_101: 3.000000e+1 2.000000e+1\n"
    f"P_rect_101: 5.000000e+1 0.000000e+0 1.500000e+1 0.000000e+0 {_ROW2_3}\n"
    "S_rect_103: 3.000000e+1 2.000000e+1\n"
    "T_103: -5.000000e-01 -7.500610e-04 -2.395167e-03\n"
    f"P_rect_103: 5.000000e+1 0.000000e+0 1.500000e+1 -5.000000e+1 {_ROW2_3}\n"
)


# ------------------------------------------------------------------------------- real data, golden values


@pytest.fixture(scope="module")
def shared_frames(shared_data: Path) -> list[Scene]:
    root = shared_data / "drivingstereo"
    if not root.is_dir():
        pytest.skip(f"{root} not present")
    return list(iter_drivingstereo(root))


def test_every_shared_frame_loads(
    shared_data: Path, shared_frames: list[Scene], check_scene: Callable[..., None]
) -> None:
    assert len(shared_frames) == 10
    names = [s.name for s in shared_frames]
    assert names == sorted(names) and names[0] == FIRST and all(n.startswith(f"{SEQ}_") for n in names)
    for s in shared_frames:
        check_scene(s, (400, 881))
        assert s.layout == "drivingstereo" and s.path == shared_data / "drivingstereo"
        assert s.image_size == (881, 400) and s.nonocc_mask is None and s.lidar_points is None
        depth = s.gt_depth
        assert depth.shape == (400, 881) and depth.dtype == np.float32 and not np.isinf(depth).any()
        assert np.nanmin(depth) > 0
        # both maps come from the same projected LiDAR: known on the same pixels, about a quarter of them
        np.testing.assert_array_equal(np.isfinite(depth), np.isfinite(s.gt_disparity))
        assert 0.2 < np.isfinite(depth).mean() < 0.3
        assert s.max_disparity == 80  # largest ground truth (< 69 px) rounded up to 16
        assert s.max_disparity >= np.nanmax(s.gt_disparity)


def test_shared_rig_golden(shared_frames: list[Scene]) -> None:
    for s in shared_frames:
        rig = s.rig
        assert rig.focal_px == pytest.approx(1003.556)  # P_rect_101[0, 0]
        assert rig.baseline_m == pytest.approx(0.5446076)  # |T_103[0]|, not P_rect_103's full-size tx
        assert rig.cx_left == pytest.approx(455.689) and rig.cx_right == pytest.approx(455.689)
        assert rig.cy == pytest.approx(197.6634) and rig.doffs == 0
        assert rig.image_size == (881, 400)
        assert rig.focal_px * rig.baseline_m == pytest.approx(546.4, abs=0.2)


def test_shared_first_frame_golden(shared_frames: list[Scene]) -> None:
    s = shared_frames[0]
    assert s.name == FIRST
    assert int(np.isfinite(s.gt_disparity).sum()) == 92105
    assert float(np.nanmax(s.gt_disparity)) == 68.625 and float(np.nanmin(s.gt_disparity)) == 4.5625
    assert float(np.nanmin(s.gt_depth)) == pytest.approx(7.9609375)
    assert float(np.nanmax(s.gt_depth)) == pytest.approx(119.40234375)


def test_disparity_times_depth_is_f_times_baseline(shared_frames: list[Scene]) -> None:
    for s in shared_frames:
        both = np.isfinite(s.gt_disparity) & np.isfinite(s.gt_depth)
        assert both.sum() > 80_000
        fb = s.rig.focal_px * s.rig.baseline_m
        product = s.gt_disparity[both].astype(np.float64) * s.gt_depth[both]
        np.testing.assert_allclose(product, fb, rtol=5e-3)  # 546.4 px m within 0.5 % on every pixel
        # the same through the rig
        np.testing.assert_allclose(s.rig.depth(s.gt_disparity)[both], s.gt_depth[both], rtol=5e-3)


def test_shared_folder_by_name_and_discovery(shared_data: Path, shared_frames: list[Scene]) -> None:
    root = shared_data / "drivingstereo"
    s = load_drivingstereo(root, f"{FIRST}.jpg")
    assert s.name == FIRST
    np.testing.assert_array_equal(s.left, shared_frames[0].left)
    assert [x.name for x in iter_scenes(root)] == [x.name for x in shared_frames]
    with pytest.raises(ValueError, match="10 scenes.*iter_scenes"):
        load_scene(root)


# ------------------------------------------------------------------------------- synthetic folders


def _frame(root: Path, name: str, rng: np.random.Generator, *, split: str = "train") -> tuple[np.ndarray, np.ndarray]:
    seq = name.split("_")[0]
    for kind in ("left-image", "right-image", "disparity-map", "depth-map"):
        (root / f"{split}-{kind}" / seq).mkdir(parents=True, exist_ok=True)
    left = rng.integers(0, 256, (20, 30, 3), dtype=np.uint8)
    write_image(root / f"{split}-left-image" / seq / f"{name}.png", left)  # lossless: .png is accepted too
    write_image(root / f"{split}-right-image" / seq / f"{name}.png", left)
    disparity = rng.uniform(2.0, 40.0, (20, 30))
    disparity[rng.random((20, 30)) < 0.7] = np.nan  # sparse, like projected LiDAR
    depth = 50.0 * 0.5 / disparity  # f B / d
    write_kitti_disparity(root / f"{split}-disparity-map" / seq / f"{name}.png", disparity)
    write_kitti_depth(root / f"{split}-depth-map" / seq / f"{name}.png", depth)
    (root / "half-image-calib").mkdir(exist_ok=True)
    (root / "half-image-calib" / f"{seq}.txt").write_text(CALIB)
    return disparity, depth


def test_synthetic_folder_round_trip(tmp_path: Path, check_scene: Callable[..., None]) -> None:
    rng = np.random.default_rng(21)
    truth = {name: _frame(tmp_path, name, rng) for name in ("2020-01-01-10-00-00_b", "2020-01-01-10-00-00_a")}
    scenes = list(iter_drivingstereo(tmp_path))
    assert [s.name for s in scenes] == ["2020-01-01-10-00-00_a", "2020-01-01-10-00-00_b"]
    for s in scenes:
        check_scene(s, (20, 30))
        disparity, depth = truth[s.name]
        np.testing.assert_allclose(s.gt_disparity, disparity, atol=1 / 512)
        np.testing.assert_allclose(s.gt_depth, depth, atol=1 / 512)
        assert s.rig.focal_px == 50.0 and s.rig.baseline_m == 0.5 and s.rig.cx_left == 15.0 and s.rig.cy == 10.0
        assert s.max_disparity == int(np.ceil(np.nanmax(disparity) / 16) * 16)
    assert [s.name for s in iter_scenes(tmp_path)] == ["2020-01-01-10-00-00_a", "2020-01-01-10-00-00_b"]


def test_test_split_and_discovery_of_both_splits(tmp_path: Path) -> None:
    rng = np.random.default_rng(22)
    _frame(tmp_path, "s1_a", rng)
    _frame(tmp_path, "s2_b", rng, split="test")
    assert load_drivingstereo(tmp_path, "s2_b", split="test").name == "s2_b"
    assert [s.name for s in iter_drivingstereo(tmp_path, split="test")] == ["s2_b"]
    assert [s.name for s in iter_scenes(tmp_path)] == ["s1_a", "s2_b"]
    with pytest.raises(FileNotFoundError, match="s2_b"):
        load_drivingstereo(tmp_path, "s2_b")  # not in the train split
    with pytest.raises(ValueError, match="`split`"):
        load_drivingstereo(tmp_path, "s1_a", split="val")
    with pytest.raises(ValueError, match="`split`"):
        list(iter_drivingstereo(tmp_path, split="val"))


def test_single_frame_folder_is_one_scene(tmp_path: Path) -> None:
    _frame(tmp_path, "s1_a", np.random.default_rng(23))
    s = load_scene(tmp_path)
    assert s.name == "s1_a" and s.layout == "drivingstereo" and s.path == tmp_path


def test_missing_right_image_is_named(tmp_path: Path) -> None:
    _frame(tmp_path, "s1_a", np.random.default_rng(24))
    _frame(tmp_path, "s1_b", np.random.default_rng(25))
    (tmp_path / "train-right-image" / "s1" / "s1_a.png").unlink()
    with pytest.raises(FileNotFoundError, match=r"right image.*s1_a\.jpg"):
        load_drivingstereo(tmp_path, "s1_a")
    with pytest.raises(FileNotFoundError, match="right image"):
        list(iter_drivingstereo(tmp_path))
    with pytest.warns(UserWarning, match="s1_a"):
        assert [s.name for s in iter_scenes(tmp_path, skip_errors=True)] == ["s1_b"]
    with pytest.raises(FileNotFoundError, match=r"left image.*s1_c"):
        load_drivingstereo(tmp_path, "s1_c")


@pytest.mark.parametrize(
    ("old", "new", "error", "match"),
    [
        ("20180703\n", "20180703\nP_rect_101 1 2 3\n", CalibrationError, "line 2 is not `key: values`"),
        ("T_103:", "T_013:", FileFormatError, "missing T_103"),
        ("P_rect_101: 5.000000e+1 ", "P_rect_101: ", FileFormatError, "P_rect_101 must have 12 numbers"),
        ("T_103: -5.000000e-01", "T_103: nan", FileFormatError, "T_103 has non-finite"),
        ("S_rect_101: 3.000000e+1", "S_rect_101: 6.000000e+1", FileFormatError, "S_rect_101 says 60x20"),
        ("P_rect_103: 5.000000e+1", "P_rect_103: 7.000000e+1", FileFormatError, "rectified pair"),
        ("T_103: -5.000000e-01", "T_103: 0.0", CalibrationError, "`baseline_m` must be > 0"),
    ],
)
def test_malformed_calibration_is_named(tmp_path: Path, old: str, new: str, error: type, match: str) -> None:
    _frame(tmp_path, "s1_a", np.random.default_rng(26))
    path = tmp_path / "half-image-calib" / "s1.txt"
    assert old in CALIB
    path.write_text(CALIB.replace(old, new))
    with pytest.raises(error, match=match) as info:
        load_drivingstereo(tmp_path, "s1_a")
    assert "s1.txt" in str(info.value)


def test_missing_maps_and_calibration_are_optional(tmp_path: Path) -> None:
    _frame(tmp_path, "s1_a", np.random.default_rng(27))
    shutil.rmtree(tmp_path / "half-image-calib")
    shutil.rmtree(tmp_path / "train-depth-map")
    s = load_drivingstereo(tmp_path, "s1_a")
    assert s.rig is None and s.gt_depth is None and s.gt_disparity is not None
    shutil.rmtree(tmp_path / "train-disparity-map")
    s = load_drivingstereo(tmp_path, "s1_a")
    assert s.gt_disparity is None and s.max_disparity is None


def test_bad_maps_are_named(tmp_path: Path) -> None:
    _frame(tmp_path, "s1_a", np.random.default_rng(28))
    disp = tmp_path / "train-disparity-map" / "s1" / "s1_a.png"
    write_kitti_disparity(disp, np.ones((10, 30)))
    with pytest.raises(FileFormatError, match=r"s1_a\.png is 30x10"):
        load_drivingstereo(tmp_path, "s1_a")
    write_image(disp, np.ones((20, 30), np.uint8))
    with pytest.raises(FileFormatError, match="16-bit"):
        load_drivingstereo(tmp_path, "s1_a")
    disp.unlink()
    depth = tmp_path / "train-depth-map" / "s1" / "s1_a.png"
    depth.write_bytes(b"\x89PNG not really")
    with pytest.raises(FileFormatError, match="depth map"):
        load_drivingstereo(tmp_path, "s1_a")


@pytest.mark.parametrize(
    ("frame", "error"),
    [("nounderscore", ValueError), ("../s1_a", ValueError), (".._a", ValueError), ("", ValueError), (7, TypeError)],
)
def test_bad_frame_names(tmp_path: Path, frame: object, error: type) -> None:
    _frame(tmp_path, "s1_a", np.random.default_rng(29))
    with pytest.raises(error, match="`frame`"):
        load_drivingstereo(tmp_path, frame)  # type: ignore[arg-type]


def test_not_a_drivingstereo_folder(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="train-left-image"):
        list(iter_drivingstereo(tmp_path))
    with pytest.raises(FileNotFoundError, match="nowhere"):
        load_drivingstereo(tmp_path / "nowhere", "s1_a")
