"""The SGM kernels on the real scenes in ../shared/data: bad-2 (unknown counted as bad) against
OpenCV StereoSGBM MODE_HH run on the same input, and census robustness to a gain/offset change.

Kernel level only (no speckle filter, no hole filling): the public API's own scene tests live in
test_accuracy.py. Margins are set from the measured numbers written next to each case.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from stereo_classic.matching._kernels.core import sgm_match


def _read_pfm(path: Path) -> np.ndarray:
    with open(path, "rb") as f:
        f.readline()
        w, h = (int(v) for v in f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype="<f4" if scale < 0 else ">f4").reshape(h, w)
    return np.flipud(data).astype(np.float32)


def _grey(path: Path) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_GRAYSCALE)
    assert img is not None, path
    return np.ascontiguousarray(img)


def _scene(root: Path, name: str):
    """(left, right, gt float32 NaN unknown, num_disparities = GT max rounded up to 16)."""
    if name == "Motorcycle":
        f = root / "middlebury2014/trainingQ/Motorcycle"
        left, right, gt = _grey(f / "im0.png"), _grey(f / "im1.png"), _read_pfm(f / "disp0GT.pfm")
        gt[~np.isfinite(gt)] = np.nan
    elif name == "Adirondack":
        f = root / "adirondackQ"
        left, right = _grey(f / "Adirondack_left.png"), _grey(f / "Adirondack_right.png")
        gt = cv2.imread(str(f / "Adirondack_gt.png"), cv2.IMREAD_UNCHANGED).astype(np.float32)
        gt[gt == 0] = np.nan
    elif name in ("Tsukuba", "Venus"):
        f = root / "middlebury2001" / name.lower()
        files = ("im3.png", "im4.png", "disp3.pgm", 16) if name == "Tsukuba" else ("im2.png", "im6.png", "disp2.pgm", 8)
        left, right = _grey(f / files[0]), _grey(f / files[1])
        gt = cv2.imread(str(f / files[2]), cv2.IMREAD_UNCHANGED).astype(np.float32) / files[3]
        gt[gt == 0] = np.nan
    else:
        f = root / "middlebury2003" / name.lower()
        left, right = _grey(f / "im2.png"), _grey(f / "im6.png")
        gt = cv2.imread(str(f / "disp2.png"), cv2.IMREAD_UNCHANGED).astype(np.float32) / 4
        gt[gt == 0] = np.nan
    num = int(np.ceil(np.nanmax(gt) / 16) * 16)
    return left, right, gt, num


def _bad2(d: np.ndarray, gt: np.ndarray) -> float:
    m = np.isfinite(gt)
    return 100.0 * float(np.mean(~(np.abs(d[m] - gt[m]) <= 2)))  # NaN compares False: unknown is bad


def _opencv_hh(left, right, num, block=5):
    m = cv2.StereoSGBM_create(minDisparity=0, numDisparities=num, blockSize=block, P1=8 * block * block,
                              P2=32 * block * block, disp12MaxDiff=1, uniquenessRatio=0, speckleWindowSize=0,
                              mode=cv2.STEREO_SGBM_MODE_HH)
    d = m.compute(left, right).astype(np.float32) / 16
    d[d < 0] = np.nan
    return d


# measured (census 9x7, p1 20, p2 80, no LR check): ours vs HH. With lr_mode="opencv" LR check
# at 1 px ours is 14.64, 12.52, 14.79, 15.29, 5.01, 4.58: still below HH on every scene.
MEASURED = {
    "Motorcycle": (13.55, 19.13),
    "Adirondack": (11.09, 19.59),
    "Cones": (13.31, 22.02),
    "Teddy": (14.26, 24.29),
    "Tsukuba": (4.41, 5.03),
    "Venus": (3.93, 9.35),
}


@pytest.mark.parametrize("name", list(MEASURED))
def test_census_kernel_beats_opencv_hh(shared_data, name):
    left, right, gt, num = _scene(shared_data, name)
    ours = _bad2(sgm_match(left, right, num_disparities=num, lr_check=None)[0], gt)
    with_lr = _bad2(sgm_match(left, right, num_disparities=num, lr_check=1.0, lr_mode="opencv")[0], gt)
    hh = _bad2(_opencv_hh(left, right, num), gt)
    expected_ours, expected_hh = MEASURED[name]
    assert ours < hh
    # HH (disp12MaxDiff=1) against ours with the same 1 px check: below on all six, Tsukuba by only
    # 0.02 points, hence the small allowance
    assert with_lr < hh + 0.1
    assert ours == pytest.approx(expected_ours, abs=0.5)
    assert hh == pytest.approx(expected_hh, abs=1.0)


def test_lr_check_only_removes_pixels_on_a_real_scene(shared_data):
    left, right, gt, num = _scene(shared_data, "Cones")
    a, _, _ = sgm_match(left, right, num_disparities=num, lr_check=None)
    b, dr, _ = sgm_match(left, right, num_disparities=num, lr_check=1.0, lr_mode="opencv", return_right=True)
    kept = np.isfinite(b)
    np.testing.assert_array_equal(a[kept], b[kept])
    assert 0.02 < np.isnan(b).mean() < 0.2
    assert _bad2(b, gt) == pytest.approx(14.79, abs=0.3)  # measured; no LR check: 13.31, "full" 1 px: 15.64
    # the pixels the check keeps are more often right than the ones it removes
    m = np.isfinite(gt)
    err = np.abs(a - gt)
    assert np.mean(err[m & kept] <= 2) > np.mean(err[m & ~kept] <= 2) + 0.3
    assert np.isfinite(dr).mean() > 0.9


@pytest.mark.parametrize("name, max_loss", [("Cones", 2.0), ("Adirondack", 2.0), ("Venus", 2.0), ("Motorcycle", 2.0)])
def test_census_survives_gain_and_offset(shared_data, name, max_loss):
    left, right, gt, num = _scene(shared_data, name)
    brighter = np.clip(right.astype(np.float64) * 1.3 + 20, 0, 255).astype(np.uint8)
    base = _bad2(sgm_match(left, right, num_disparities=num, lr_check=None)[0], gt)
    changed = _bad2(sgm_match(left, brighter, num_disparities=num, lr_check=None)[0], gt)
    assert changed - base <= max_loss  # measured +0.3 (Cones) .. +1.3 (Motorcycle)


def test_sad_collapses_less_than_raw_intensity_would_on_adirondack(shared_data):
    # Adirondack's cameras differ in exposure; the Sobel prefilter keeps SAD usable there
    left, right, gt, num = _scene(shared_data, "Adirondack")
    sad = _bad2(sgm_match(left, right, cost="sad", num_disparities=num, p1=200, p2=800, lr_check=None)[0], gt)
    assert sad < 15.0  # measured 12.6; raw-intensity SAD: 57 (SGM_NOTES)
