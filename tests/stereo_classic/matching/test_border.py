"""The left-border check (``SGMParams.border_check``, ``stereo_classic.matching.border``)."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_classic.matching import SGMParams, compute_disparity, estimate_memory
from stereo_classic.matching.border import STRIP_MARGIN, confirm_left_border, left_border_columns


def _shift_pair(shift: int, h: int = 40, w: int = 120, seed: int = 0):
    """A textured right image and the left one that sees it ``shift`` px to the right (true d = shift everywhere,
    measurable only where x >= shift)."""
    rng = np.random.default_rng(seed)
    right = rng.integers(0, 256, (h, w), dtype=np.uint8)
    right = np.ascontiguousarray(np.repeat(np.repeat(right[::2, ::2], 2, 0), 2, 1)[:h, :w])  # 2 px blobs
    left = np.roll(right, shift, axis=1)
    left[:, :shift] = rng.integers(0, 256, (h, shift), dtype=np.uint8)  # what only the left camera sees
    return np.ascontiguousarray(left), right


def test_left_border_columns():
    assert left_border_columns(np.array([True, True, False, True])) == 2
    assert left_border_columns(np.array([False, True])) == 0
    assert left_border_columns(np.ones(5, bool)) == 5
    assert left_border_columns(np.zeros(0, bool)) == 0


def test_measurable_border_pixels_are_kept_and_the_others_stay_unknown():
    """32 disparities, border_reach 0.5: columns 0..14 search fewer than 16. The truth (10 px) is within reach from
    column 10 on (its census window from column 11): with the check those columns are measured and right, the
    columns before it stay unknown."""
    left, right = _shift_pair(10)
    params = SGMParams(num_disparities=32, subpixel=False, threads=1)
    plain = compute_disparity(left, right, params)
    checked = compute_disparity(left, right, params, border_check=True)
    assert np.isnan(plain.disparity[:, :15]).all() and np.isfinite(plain.disparity[:, 15]).any()
    kept = checked.disparity[2:-2, 11:15]  # away from the top and bottom rows' windows
    assert np.isfinite(kept).mean() > 0.9 and (kept[np.isfinite(kept)] == 10).all()
    assert np.isfinite(checked.disparity[:, :9]).mean() < 0.05  # the truth is out of their reach
    np.testing.assert_array_equal(checked.disparity[:, 15:], plain.disparity[:, 15:])  # the interior as it was
    assert checked.validity["short_range"] < plain.validity["short_range"]
    v = checked.validity
    assert v["unknown_matcher"] + v["short_range"] + v["speckle_removed"] + v["valid"] - v["filled"] == left.size
    assert checked.timings_ms["border_check"] > 0 and "border_check" not in plain.timings_ms


def test_without_lr_check_nothing_is_confirmed():
    left, right = _shift_pair(10)
    params = SGMParams(num_disparities=32, lr_check=None, threads=1)
    a = compute_disparity(left, right, params)
    b = compute_disparity(left, right, params, border_check=True)
    np.testing.assert_array_equal(a.filled_disparity, b.filled_disparity)


def test_confirm_reads_the_mirrored_strip():
    """confirm_left_border calls the matcher once, on the pair's first columns mirrored (right image first)."""
    left, right = _shift_pair(6, w=200)
    params = SGMParams(num_disparities=16, threads=1)
    seen = []

    def match(a, b, p):
        seen.append((a.copy(), b.copy(), p))
        return compute_disparity(a, b, p)

    disparity = compute_disparity(left, right, params.replace(border_reach=0.0)).disparity
    keep = confirm_left_border(left, right, disparity, 8, params, match)
    (a, b, p), = seen
    width = 8 + 16 + STRIP_MARGIN
    np.testing.assert_array_equal(a, right[:, :width][:, ::-1])
    np.testing.assert_array_equal(b, left[:, :width][:, ::-1])
    assert not p.border_check and not p.fill_holes and p.border_reach == 0.0
    assert keep.shape == (left.shape[0], 8) and not keep[:, :5].any()  # the truth, 6 px, is out of their reach
    assert keep[:, 7].mean() > 0.75 and (keep <= np.isfinite(disparity[:, :8])).all()  # only the left view's winners


def test_memory_counts_the_strip():
    params = SGMParams(num_disparities=64)
    assert estimate_memory((480, 640), params.replace(border_check=True)) > estimate_memory((480, 640), params)


@pytest.mark.parametrize("name", ["Laundry"])
def test_real_border_strip_is_more_often_right(shared_data, name):
    """On Laundry, whose left edge shows a curtain far behind the first measured pixels (the basket), the filled
    border strip is wrong much less often with the check (0.98 -> 0.71 of its pixels when measured)."""
    from benchmarks.scenes import disparity_range, load_scenes

    scenes = [s for s in load_scenes(shared_data) if s.name == name and s.gt_disparity is not None]
    if not scenes:
        pytest.skip(f"{name} is not in {shared_data}")
    scene = scenes[0]
    num = disparity_range(scene)
    params = SGMParams(num_disparities=num, block_size=5, threads=2)
    columns = int(np.ceil(params.border_reach * num))
    gt = scene.gt_disparity[:, :columns]
    known = np.isfinite(gt)

    def wrong(dmap):
        return float(np.mean(np.abs(dmap.filled_disparity[:, :columns][known] - gt[known]) > 2))

    assert wrong(compute_disparity(scene.left, scene.right, params, border_check=True)) < (
        wrong(compute_disparity(scene.left, scene.right, params)) - 0.15)
