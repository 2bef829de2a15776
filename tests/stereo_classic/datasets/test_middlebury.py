"""stereo_classic.datasets.middlebury: 2014 golden values, 2001-2006 scales, named pairs, ndisp."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from calib import CalibrationError
from stereo_classic.datasets import load_middlebury2014, load_middlebury_classic, load_named_pair, load_scene
from stereo_classic.io import FileFormatError, write_image, write_scaled_disparity


def _pair(rng: np.random.Generator, h: int = 20, w: int = 30) -> tuple[np.ndarray, np.ndarray]:
    return rng.integers(0, 256, (h, w, 3), dtype=np.uint8), rng.integers(0, 256, (h, w, 3), dtype=np.uint8)


def test_middlebury2014_motorcycle_golden(shared_data: Path, check_scene: Callable[..., None]) -> None:
    s = load_middlebury2014(shared_data / "middlebury2014" / "trainingQ" / "Motorcycle")
    check_scene(s, (497, 741))
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
def test_middlebury_classic_scales(shared_data: Path, folder: str, shape: tuple[int, int], gt_max: float, step: float, max_disp: int, check_scene: Callable[..., None]) -> None:
    s = load_middlebury_classic(shared_data / folder)
    check_scene(s, shape)
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


def test_adirondack_named_pair(shared_data: Path, check_scene: Callable[..., None]) -> None:
    s = load_named_pair(shared_data / "adirondackQ")
    check_scene(s, (497, 720))
    assert s.name == "Adirondack" and float(np.nanmax(s.gt_disparity)) == 60.0
    assert s.max_disparity == 64
    assert 0.85 < s.nonocc_mask.mean() < 0.95
    assert load_scene(shared_data / "adirondackQ").name == "Adirondack"


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
