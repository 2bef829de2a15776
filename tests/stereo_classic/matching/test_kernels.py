"""The numba SGM kernels against the slow numpy reference, exactly, plus synthetic ground truth.

Small random images keep the pure-Python reference fast. Real-scene checks live in
test_kernels_scenes.py.
"""

from __future__ import annotations

import ast
import os
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stereo_classic.matching import reference as ref
from stereo_classic.matching._kernels import core

P1, P2 = 10, 120


def _pair(seed: int, h: int = 12, w: int = 22, shift: int = 3, noise: int = 12):
    """A random left image and a right image made from it with a global shift plus noise."""
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, (h, w), dtype=np.uint8)
    right = np.roll(left, -shift, axis=1).astype(np.int64)
    right[:, w - shift:] = rng.integers(0, 256, (h, shift))
    right = np.clip(right + rng.integers(-noise, noise + 1, right.shape), 0, 255).astype(np.uint8)
    return np.ascontiguousarray(left), np.ascontiguousarray(right)


def _textured(h: int, w: int, seed: int) -> np.ndarray:
    """Smooth random texture (float, 0..255): sums of random sinusoids, no repetition at small scale."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    img = np.zeros((h, w))
    for _ in range(40):
        fx, fy = rng.uniform(0.05, 0.9, 2) * rng.choice([-1, 1], 2)
        img += rng.uniform(0.3, 1.0) * np.sin(fx * x + fy * y + rng.uniform(0, 2 * np.pi))
    img -= img.min()
    return img / img.max() * 255.0


def _sample_rows(img: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """img sampled at float column positions xs (H, W) with linear interpolation, per row."""
    h, w = img.shape
    out = np.empty(xs.shape)
    cols = np.arange(w)
    for y in range(h):
        out[y] = np.interp(xs[y], cols, img[y])
    return out


# ---------------------------------------------------------------------------------------------
# cost volume


@pytest.mark.parametrize("cost", ["census", "sad", "census+grad"])
@pytest.mark.parametrize("dmin, D", [(0, 8), (-3, 8), (2, 16), (5, 30)])
def test_cost_volume_matches_reference(cost, dmin, D):
    left, right = _pair(1)
    kw = dict(cost=cost, min_disparity=dmin, num_disparities=D, block_size=5, census_window=(9, 7), p2=P2)
    got = core.cost_volume(left, right, **kw)
    want = ref.cost_volume_reference(left, right, **kw)
    assert got.dtype == np.int16 and got.shape == left.shape + (D,)
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("census_window", [(5, 5), (7, 5), (9, 7), (3, 3)])
def test_census_windows_match_reference(census_window):
    left, right = _pair(2)
    kw = dict(cost="census", min_disparity=0, num_disparities=8, census_window=census_window, p2=P2)
    np.testing.assert_array_equal(core.cost_volume(left, right, **kw), ref.cost_volume_reference(left, right, **kw))


@pytest.mark.parametrize("cost", ["sad", "census+grad"])
@pytest.mark.parametrize("block_size", [1, 3, 7, 9, 15, 21])
def test_sad_block_sizes_match_reference(block_size, cost):
    """Every window size, for the SAD cost and the gradient term of census+grad (its window mean: the sum times
    round(1024 / block**2), shifted; block 9's products come closest to 2**16)."""
    left, right = _pair(3, h=9 + block_size, w=16 + block_size)
    kw = dict(cost=cost, min_disparity=-1, num_disparities=6, block_size=block_size, p2=P2)
    np.testing.assert_array_equal(core.cost_volume(left, right, **kw), ref.cost_volume_reference(left, right, **kw))


@pytest.mark.parametrize("block_size", range(1, 22, 2))
def test_gradient_term_at_its_largest_window_sums(block_size):
    """census+grad where |Sobel_x(L) - Sobel_x(R)| is 2 * SOBEL_CAP wherever no ramp wraps (ramps of 8 grey levels a
    pixel, rising on the left, falling on the right, 32 pixels a period), so that window sums reach their largest,
    2 * SOBEL_CAP * block**2: the row cost's product in 16 bits (``mullo16``, every block size whose largest sum times
    grad_mul is below 2**16) and its high-half product (15, 17, 19) against the reference, every block size."""
    from stereo_classic.matching._kernels.cost import SOBEL_CAP, sad_prefilter

    x = np.arange(80)
    left = np.tile(((x * 8) % 256).astype(np.uint8), (block_size + 6, 1))
    right = np.tile((255 - (x * 8) % 256).astype(np.uint8), (block_size + 6, 1))
    ad = np.abs(sad_prefilter(left)[0].astype(np.int64) - sad_prefilter(right)[0])  # disparity 0
    windows = np.lib.stride_tricks.sliding_window_view(ad, (block_size, block_size)).sum(axis=(2, 3))
    assert windows.max() == 2 * SOBEL_CAP * block_size**2  # the largest sum is reached
    kw = dict(cost="census+grad", min_disparity=0, num_disparities=6, block_size=block_size, p2=P2)
    np.testing.assert_array_equal(core.cost_volume(left, right, **kw), ref.cost_volume_reference(left, right, **kw))


def test_mullo16_is_the_product_modulo_2_16_shifted():
    """``intrinsics.mullo16(a, m, n)``: ``(a * m) >> n`` with the product taken modulo 2**16 and read as unsigned (exact
    below 2**16, the row cost's case), in a loop numba vectorises as the row cost's."""
    from numba import njit

    from stereo_classic.matching._kernels.intrinsics import mullo16

    @njit(cache=False)
    def run(a, m, n, out):  # pragma: no cover - numba
        for i in range(a.shape[0]):
            out[i] = mullo16(a[i], m, n)

    a = np.random.default_rng(5).integers(0, 32768, 4099).astype(np.int16)
    for m, n in ((41, 10), (1024, 10), (13, 10), (114, 10), (5, 10), (3, 0), (2, 1)):
        out = np.empty_like(a)
        run(a, np.int16(m), np.int16(n), out)
        expect = (((a.astype(np.int64) * m) % 65536) >> n).astype(np.uint16).view(np.int16)
        np.testing.assert_array_equal(out, expect)


def test_umin16_minimum_equals_the_signed_one_on_non_negative_values():
    """``intrinsics.umin16``, the one-sweep kernel's minimum over a path vector (from 65535 read as unsigned, -1): the
    signed minimum wherever the values are non-negative (path values and sums are: costs are clipped at 0, and a
    path value is its cost plus a non-negative penalty term), in a reduction loop numba vectorises as the kernel's;
    a negative value reads as above 32767 and is skipped (the reason the kernel may use it only there)."""
    from numba import njit

    from stereo_classic.matching._kernels.intrinsics import umin16

    @njit(cache=False)
    def smallest(a):  # pragma: no cover - numba
        m = np.int16(-1)
        for i in range(a.shape[0]):
            m = umin16(m, a[i])
        return m

    rng = np.random.default_rng(6)
    for n in (1, 31, 64, 128, 4099):
        a = rng.integers(0, 32768, n).astype(np.int16)
        assert smallest(a) == a.min()
        a[n // 2] = 0
        assert smallest(a) == 0
    b = np.array([5, -3, 7] * 30, np.int16)
    assert smallest(b) == 5  # -3 is 65533 unsigned


def test_census_is_invariant_to_gain_and_offset():
    left, _ = _pair(4)
    bright = np.clip(left.astype(np.float64) * 1.3 + 20, 0, 255).astype(np.uint8)
    # where nothing saturates, the order of intensities (and so every census bit) is unchanged
    a = core.cost_volume(left, left, num_disparities=4)
    b = core.cost_volume(left, bright, num_disparities=4)
    ok = (left.astype(np.float64) * 1.3 + 20 <= 255).all()
    assert not ok or np.array_equal(a, b)
    assert (a[:, :, 0] == 0).all()  # a pixel against itself


# ---------------------------------------------------------------------------------------------
# aggregation: every direction, exactly


@pytest.mark.parametrize("cost", ["census", "sad", "census+grad"])
@pytest.mark.parametrize("direction", range(8))
@pytest.mark.parametrize("dmin, D", [(0, 8), (-3, 12)])
def test_each_direction_matches_reference(cost, direction, dmin, D):
    left, right = _pair(10 + direction)
    kw = dict(cost=cost, min_disparity=dmin, num_disparities=D, block_size=5, census_window=(9, 7))
    shift, _ = core.cost_scale(cost, 5, (9, 7), P2)
    C = ref.cost_volume_reference(left, right, p2=P2, **kw)
    want = ref.path_reference(C, direction, P1 >> shift, P2 >> shift)
    got = core.sum_volume(left, right, path_mask=1 << direction, p1=P1, p2=P2, **kw)
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("direction", [0, 2, 5, 7])
def test_adaptive_p2_direction_matches_reference(direction):
    left, right = _pair(20 + direction)
    C = ref.cost_volume_reference(left, right, num_disparities=10, p2=P2)
    want = ref.path_reference(C, direction, P1, P2, image=left)
    got = core.sum_volume(left, right, path_mask=1 << direction, num_disparities=10, p1=P1, p2=P2, adaptive_p2=True)
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("mask", [core.ALL_PATHS, core.FOUR_PATHS, core.THREE_PATHS, 0b10100101])
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("shape", [(12, 22), (1, 19), (2, 9), (7, 40)])
def test_path_sums_match_reference(mask, threads, shape):
    left, right = _pair(30, h=shape[0], w=shape[1], shift=2)
    C = ref.cost_volume_reference(left, right, min_disparity=-2, num_disparities=9, p2=P2)
    want = ref.sum_reference(C, mask, P1, P2)
    got = core.sum_volume(left, right, path_mask=mask, threads=threads, min_disparity=-2, num_disparities=9,
                          p1=P1, p2=P2)
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("threads", [1, 2])
def test_default_cost_and_paths_match_reference(threads):
    """census+grad over the three default directions (left, top, right), as the default matcher runs them."""
    left, right = _pair(31, h=11, w=30, shift=3)
    kw = dict(cost="census+grad", min_disparity=-1, num_disparities=10, block_size=5, census_window=(9, 7))
    C = ref.cost_volume_reference(left, right, p2=112, **kw)
    want = ref.sum_reference(C, core.THREE_PATHS, 28, 112)
    got = core.sum_volume(left, right, path_mask=core.THREE_PATHS, threads=threads, p1=28, p2=112, **kw)
    np.testing.assert_array_equal(got, want)


def _weak_texture_pair(seed: int, h: int = 12, w: int = 30, shift: int = 3):
    """A pair whose left half is nearly flat (grey 100 +- 1: weak texture, raised penalties) and whose right half is
    random (strong texture, penalties as given), with a slow ramp in between."""
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, (h, w)).astype(np.int64)
    left[:, : w // 2] = 100 + rng.integers(-1, 2, (h, w // 2))
    left[:, w // 2 - 4: w // 2] = 100 + 3 * np.arange(4)[None, :] + rng.integers(0, 2, (h, 4))
    right = np.roll(left, -shift, axis=1)
    right[:, w - shift:] = rng.integers(0, 256, (h, shift))
    right = np.clip(right + rng.integers(-2, 3, right.shape), 0, 255)
    return np.ascontiguousarray(left.astype(np.uint8)), np.ascontiguousarray(right.astype(np.uint8))


def test_weak_texture_scale_is_the_documented_integer_formula():
    from stereo_classic.matching._kernels.cost import TEXTURE_REFERENCE, TEXTURE_WINDOW
    from stereo_classic.matching._kernels.texture import weak_texture_scale

    left, _ = _weak_texture_pair(3, h=20, w=40)
    got = weak_texture_scale(left, 4.0)
    img = np.pad(left.astype(np.int64), 1, mode="edge")
    sobel = np.abs((img[:-2, 2:] - img[:-2, :-2]) + 2 * (img[1:-1, 2:] - img[1:-1, :-2]) + (img[2:, 2:] - img[2:, :-2]))
    r = TEXTURE_WINDOW // 2
    padded = np.pad(sobel, r, mode="edge")
    sums = sum(padded[dy:dy + 20, dx:dx + 40] for dy in range(TEXTURE_WINDOW) for dx in range(TEXTURE_WINDOW))
    mean = sums / TEXTURE_WINDOW**2
    with np.errstate(divide="ignore"):
        want = np.clip(np.floor(16 * TEXTURE_REFERENCE / mean + 0.5), 16, 64)
    np.testing.assert_array_equal(got, want)
    assert got.dtype == np.uint8 and got[:, :10].min() == 64 and got[:, -10:].max() == 16  # flat: x4; random: x1
    assert (weak_texture_scale(left, 1.0) == 16).all()  # gain 1: the penalties as given everywhere
    assert weak_texture_scale(np.full((8, 9), 7, np.uint8), 2.5).tolist() == [[40] * 9] * 8  # flat: the gain


@pytest.mark.parametrize("h, w", [(1, 1), (3, 2), (6, 7), (37, 53)])
def test_weak_texture_rows_in_any_stripes_are_the_whole_image(h, w):
    """The weak-texture factors made stripe by stripe (as ``_prepare_cost``'s workers make them) equal the whole
    image's, which the test above checks against the formula, for every cut, images smaller than the window too."""
    import cv2

    from stereo_classic.matching._kernels.texture import texture_table, weak_texture_rows, weak_texture_scale

    rng = np.random.default_rng(h * 100 + w)
    left = rng.integers(0, 256, (h, w), dtype=np.uint8)
    left[:, : w // 2] //= 32  # weak texture on the left half
    whole = weak_texture_scale(left, 4.0)
    padded = cv2.copyMakeBorder(left, 1, 1, 1, 1, cv2.BORDER_REPLICATE)
    for _ in range(4):
        cuts = sorted({0, h, *rng.integers(0, h + 1, 3).tolist()})
        got = np.zeros_like(left)
        for y0, y1 in zip(cuts[:-1], cuts[1:]):
            weak_texture_rows(padded, y0, y1, texture_table(4.0), got)
        np.testing.assert_array_equal(got, whole)
    assert texture_table(1.0).tolist() == [16]  # gain 1: 16 everywhere


@pytest.mark.parametrize("gain", [1.5, 2.5, 4.0, 8.0])  # 8: MAX_TEXTURE_GAIN
def test_scale_of_sum_is_the_table_for_every_window_sum(gain):
    """``weak_texture_rows`` computes the factor of a window sum in float32 (``scale_of_sum``) where it looked it up:
    the table's entry for every sum a window can have (0 .. 25 * 1020; past the table, 16)."""
    from numba import njit

    from stereo_classic.matching._kernels.texture import scale_of_sum, texture_table

    @njit
    def every(top, out):
        for s in range(out.shape[0]):
            out[s] = scale_of_sum(np.int16(s), top)

    table = texture_table(gain)
    got = np.zeros(25 * 1020 + 1, np.uint8)
    every(np.float32(table[0]), got)
    want = table[np.minimum(np.arange(got.size), table.size - 1)]
    np.testing.assert_array_equal(got, want)


def test_first_equal_is_the_first_index_of_a_value():
    """``select.first_equal`` (whole blocks of 32 lanes by a vector compare read as a mask, then one by one) is the
    first index of the value, in rows of any length, and _INT16_MAX where the value is absent."""
    from stereo_classic.matching._kernels.select import _INT16_MAX, first_equal

    rng = np.random.default_rng(5)
    for n in (1, 5, 31, 32, 33, 64, 95, 128, 160):
        for _ in range(30):
            row = rng.integers(0, 6, 3 * n + 7).astype(np.int16)
            start = int(rng.integers(0, 2 * n + 8))
            value = np.int16(rng.integers(0, 7))
            hits = np.flatnonzero(row[start:start + n] == value)
            want = int(hits[0]) if hits.size else _INT16_MAX
            assert first_equal(row, start, n, value) == want


@pytest.mark.parametrize("cost, paths, adaptive", [("census+grad", 3, False), ("census+grad", 8, False),
                                                    ("sad", 3, True), ("census", 4, True), ("sad", 8, False)])
@pytest.mark.parametrize("threads", [1, 2])
def test_weak_texture_penalties_match_reference(cost, paths, adaptive, threads):
    """Both kernels (one sweep for 3 paths, two passes for 4 and 8) with per-pixel penalties: P1 and P2 times the
    pixel's weak-texture factor, against the reference given the same factors; the SAD cost's scaling leaves room
    for the largest P2."""
    from stereo_classic.matching._kernels.texture import weak_texture_scale

    left, right = _weak_texture_pair(41)
    scale = weak_texture_scale(left, 4.0)
    assert scale.min() == 16 and scale.max() == 64
    p1, p2 = (28, 112) if cost != "sad" else (200, 800)
    kw = dict(cost=cost, min_disparity=-1, num_disparities=9, block_size=5, census_window=(9, 7))
    shift, _ = core.cost_scale(cost, 5, (9, 7), (p2 * 64 + 8) >> 4)
    C = ref.cost_volume_reference(left, right, p2=(p2 * 64 + 8) >> 4, **kw)
    mask = core.PATH_MASKS[paths]
    want = ref.sum_reference(C, mask, p1 >> shift, p2 >> shift, image=left if adaptive else None, scale=scale)
    got = core.sum_volume(left, right, path_mask=mask, threads=threads, p1=p1, p2=p2, adaptive_p2=adaptive,
                          weak_texture_gain=4.0, **kw)
    np.testing.assert_array_equal(got, want)
    plain = ref.sum_reference(C, mask, p1 >> shift, p2 >> shift, image=left if adaptive else None)
    assert not np.array_equal(got, plain)  # the factors changed the sums


@pytest.mark.parametrize("cost, paths, adaptive, p1_cross, cross_texture", [
    ("census+grad", 3, False, 28, False), ("census+grad", 8, False, 28, False), ("census+grad", 3, True, 19, False),
    ("sad", 4, True, 90, False), ("census", 8, False, 13, True), ("census+grad", 3, False, 60, True)])
@pytest.mark.parametrize("threads", [1, 2])
def test_cross_row_p1_matches_reference(cost, paths, adaptive, p1_cross, cross_texture, threads):
    """Both kernels with a P1 of their own on the paths that cross rows (vertical and diagonal), with or without the
    weak-texture factor, against the reference; the horizontal paths keep P1 times the factor."""
    from stereo_classic.matching._kernels.texture import weak_texture_scale

    left, right = _weak_texture_pair(43)
    scale = weak_texture_scale(left, 4.0)
    p1, p2 = (28, 112) if cost != "sad" else (200, 800)
    kw = dict(cost=cost, min_disparity=-1, num_disparities=9, block_size=5, census_window=(9, 7))
    shift, _ = core.cost_scale(cost, 5, (9, 7), (p2 * 64 + 8) >> 4)
    C = ref.cost_volume_reference(left, right, p2=(p2 * 64 + 8) >> 4, **kw)
    mask = core.PATH_MASKS[paths]
    image = left if adaptive else None
    want = ref.sum_reference(C, mask, p1 >> shift, p2 >> shift, image=image, scale=scale,
                             p1_cross=p1_cross >> shift, cross_texture=cross_texture)
    got = core.sum_volume(left, right, path_mask=mask, threads=threads, p1=p1, p2=p2, adaptive_p2=adaptive,
                          weak_texture_gain=4.0, p1_cross=p1_cross, cross_texture=cross_texture, **kw)
    np.testing.assert_array_equal(got, want)
    same = ref.sum_reference(C, mask, p1 >> shift, p2 >> shift, image=image, scale=scale)
    assert not np.array_equal(got, same)  # the rows-crossing P1 changed the sums


@pytest.mark.parametrize("cost, paths", [("census+grad", 3), ("census", 8), ("census+grad", 4)])
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("dmin", [0, -2])
def test_neutral_outside_cost_matches_reference(cost, paths, threads, dmin):
    """A match outside the right image at a neutral cost (``outside_cost``): the sums of both kernels against the
    reference given that cost, and the disparity: a winner outside the right image is unknown."""
    left, right = _pair(45, h=10, w=30, shift=3)
    kw = dict(cost=cost, min_disparity=dmin, num_disparities=12, block_size=5, census_window=(9, 7))
    C = ref.cost_volume_reference(left, right, p2=112, outside_cost=31, **kw)
    mask = core.PATH_MASKS[paths]
    want = ref.sum_reference(C, mask, 28, 112)
    got = core.sum_volume(left, right, path_mask=mask, threads=threads, p1=28, p2=112, outside_cost=31, **kw)
    np.testing.assert_array_equal(got, want)
    forbidden = core.sum_volume(left, right, path_mask=mask, threads=threads, p1=28, p2=112, **kw)
    assert not np.array_equal(got, forbidden)
    d, _, _ = core.sgm_match(left, right, paths=paths, threads=threads, p1=28, p2=112, outside_cost=31, **kw)
    d_ref, _ = ref.select_reference(want, dmin, lr_check=1.0)
    np.testing.assert_array_equal(np.isnan(d), np.isnan(d_ref))
    np.testing.assert_allclose(d[np.isfinite(d)], d_ref[np.isfinite(d_ref)], atol=1e-5)


def test_a_winner_outside_the_right_image_is_unknown():
    """A left band whose own candidates all cost the most (their match is noise) and a neutral outside cost: the
    winners there lie outside the right image and are unknown, never a disparity that merely fits."""
    rng = np.random.default_rng(46)
    right = rng.integers(0, 256, (12, 40), dtype=np.uint8)
    left = np.roll(right, 9, axis=1)
    left[:, :9] = rng.integers(0, 256, (12, 9), dtype=np.uint8)  # seen by the left camera only (true d = 9)
    kw = dict(cost="census+grad", num_disparities=16, p1=28, p2=112, paths=3, lr_check=None, threads=1)
    neutral, _, _ = core.sgm_match(np.ascontiguousarray(left), right, outside_cost=31, **kw)
    forbidden, _, _ = core.sgm_match(np.ascontiguousarray(left), right, **kw)
    assert np.isfinite(forbidden[:, :6]).all()  # forced to a disparity that fits
    assert np.isnan(neutral[:, :6]).mean() > 0.8
    np.testing.assert_array_equal(neutral[:, 24:], forbidden[:, 24:])  # the paths settle away from the band


def test_cross_row_p1_is_bounded_by_p2():
    left, right = _pair(44)
    with pytest.raises(ValueError, match="p1_cross"):
        core.sum_volume(left, right, path_mask=core.THREE_PATHS, p1=20, p2=80, p1_cross=81)


def test_weak_texture_gain_is_bounded_by_the_int16_sums():
    core.check_penalties("census", 5, (9, 7), 100, 336, 4.0)  # 336 * 4 = 1344: the largest census P2 at a pixel
    with pytest.raises(ValueError, match="weak_texture_gain"):
        core.check_penalties("census", 5, (9, 7), 100, 337, 4.0)


def test_sums_stay_inside_int16_at_the_largest_p2():
    # worst case for the bounds: no texture on one side, maximum-cost noise on the other, largest p2
    rng = np.random.default_rng(5)
    left = rng.integers(0, 256, (10, 30), dtype=np.uint8)
    right = np.zeros_like(left)
    for cost, p2 in [("census", 1344), ("sad", 5000)]:
        core.check_penalties(cost, 5, (9, 7), 100, p2)
        C = ref.cost_volume_reference(left, right, cost=cost, num_disparities=12, p2=p2)
        shift, _ = core.cost_scale(cost, 5, (9, 7), p2)
        want = ref.sum_reference(C, core.ALL_PATHS, 100 >> shift, p2 >> shift)
        assert want.max() <= 32767
        got = core.sum_volume(left, right, cost=cost, num_disparities=12, p1=100, p2=p2)
        np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("cost", ["census+grad", "sad"])
def test_three_paths_with_adaptive_p2_match_reference(cost):
    """The one-sweep kernel (paths=3) with P2 divided by the intensity step along each of its directions."""
    left, right = _pair(26, h=10, w=28)
    p1, p2 = (28, 112) if cost == "census+grad" else (200, 800)
    kw = dict(cost=cost, min_disparity=-2, num_disparities=9, block_size=5, census_window=(9, 7))
    shift, _ = core.cost_scale(cost, 5, (9, 7), p2)
    C = ref.cost_volume_reference(left, right, p2=p2, **kw)
    want = sum(ref.path_reference(C, k, p1 >> shift, p2 >> shift, image=left) for k in (0, 1, 4))
    got = core.sum_volume(left, right, path_mask=core.THREE_PATHS, p1=p1, p2=p2, adaptive_p2=True, **kw)
    np.testing.assert_array_equal(got, want)


@pytest.mark.parametrize("census_window", [(9, 7), (7, 7), (3, 3), (5, 3)])
def test_census_quarters_are_the_census_codes_bit_for_bit(census_window):
    from stereo_classic.matching._kernels.cost import census_quarters

    img = np.random.default_rng(7).integers(0, 256, (13, 37), dtype=np.uint8)
    codes = ref.census_reference(img, census_window)
    quarters = census_quarters(img, census_window)  # (H, 4, W): quarter q of row y's codes is a plane
    assert quarters.dtype == np.uint16 and quarters.shape == (13, 4, 37)
    np.testing.assert_array_equal(quarters, codes.view(np.uint16).reshape(13, 37, 4).transpose(0, 2, 1))


@pytest.mark.parametrize("cost", ["census", "census+grad", "sad"])
def test_cost_images_made_in_stripes_equal_the_whole_image_ones_for_any_thread_count(cost):
    """The driver makes the census quarters and the Sobel channel of both views by stripes of rows on the workers,
    into the workspace's arrays: the same as ``census_quarters`` and ``sad_prefilter`` of each whole image."""
    from stereo_classic.matching._kernels.core import Workspace, _prepare_cost
    from stereo_classic.matching._kernels.cost import census_quarters, sad_prefilter

    rng = np.random.default_rng(3)
    left, right = (rng.integers(0, 256, (150, 61), dtype=np.uint8) for _ in range(2))  # three stripes
    workspace = Workspace()
    for threads in (1, 2, 3, 5):
        images = _prepare_cost(left, right, cost, (9, 7), threads, workspace)
        for img, code, sob, inten in ((left, images.left_code, images.left_sobel, images.left_intensity),
                                      (right, images.right_code, images.right_sobel, images.right_intensity)):
            if cost != "sad":
                np.testing.assert_array_equal(code, census_quarters(img, (9, 7)))
            if cost != "census":
                np.testing.assert_array_equal(sob, sad_prefilter(img)[0])
            if cost == "sad":
                np.testing.assert_array_equal(inten, sad_prefilter(img)[1])
            else:
                assert inten.size == 1  # not read: a placeholder


# ---------------------------------------------------------------------------------------------
# selection: WTA, uniqueness, subpixel, right view, LR check


@pytest.mark.parametrize("dmin, D", [(0, 8), (-3, 8), (2, 16)])
@pytest.mark.parametrize("uniqueness, lr_check, subpixel", [
    (0.0, 1.0, True), (0.1, None, True), (0.05, 0.0, False), (0.0, 2.0, True), (0.3, 1.0, True)])
@pytest.mark.parametrize("lr_mode", ["full", "opencv"])
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("paths", [8, 3])  # the two-pass kernel and the one-sweep kernel (paths=3)
def test_selection_matches_reference(dmin, D, uniqueness, lr_check, subpixel, lr_mode, threads, paths):
    left, right = _pair(40, h=11, w=26)
    kw = dict(min_disparity=dmin, num_disparities=D, p1=P1, p2=P2)
    S = core.sum_volume(left, right, path_mask=core.PATH_MASKS[paths], **kw)
    d, dr, timings = core.sgm_match(left, right, uniqueness=uniqueness, lr_check=lr_check, subpixel=subpixel,
                                    threads=threads, return_right=True, lr_mode=lr_mode, paths=paths, **kw)
    wd, wdr = ref.select_reference(S, dmin, uniqueness=uniqueness, lr_check=lr_check, subpixel=subpixel,
                                   lr_mode=lr_mode)
    assert d.dtype == np.float32 and d.shape == left.shape and dr.shape == left.shape
    np.testing.assert_array_equal(d, wd)
    np.testing.assert_array_equal(dr, wdr)
    assert set(timings) >= {"cost", "aggregate", "select", "n_failed_uniqueness", "n_failed_lr"}
    unfiltered, _ = ref.select_reference(S, dmin, uniqueness=0.0, lr_check=None)
    n_nan = int(np.isnan(d).sum()) - int(np.isnan(unfiltered).sum())
    assert timings["n_failed_uniqueness"] + timings["n_failed_lr"] == n_nan
    if uniqueness == 0.0:
        assert timings["n_failed_uniqueness"] == 0
    if lr_check is None:
        assert timings["n_failed_lr"] == 0


def test_filters_only_remove_pixels():
    left, right = _pair(41, h=14, w=30)
    base, _, _ = core.sgm_match(left, right, num_disparities=10, lr_check=None, uniqueness=0.0)
    for kw in [dict(lr_check=0.0), dict(uniqueness=0.2), dict(lr_check=1.0, uniqueness=0.1)]:
        d, _, _ = core.sgm_match(left, right, num_disparities=10, **{"lr_check": None, **kw})
        kept = np.isfinite(d)
        assert np.isnan(d).sum() >= np.isnan(base).sum()
        np.testing.assert_array_equal(d[kept], base[kept])
    assert np.isfinite(base).all()  # no filter, positive range: every pixel has a candidate


def test_right_view_is_optional_and_does_not_change_the_left_view():
    left, right = _pair(43, h=12, w=30)
    d0, r0, _ = core.sgm_match(left, right, num_disparities=10, lr_check=None)
    d1, r1, _ = core.sgm_match(left, right, num_disparities=10, lr_check=None, return_right=True)
    d2, r2, _ = core.sgm_match(left, right, num_disparities=10, lr_check=1.0, lr_mode="opencv", return_right=True)
    d3, r3, _ = core.sgm_match(left, right, num_disparities=10, lr_check=1.0, lr_mode="opencv")
    d4, r4, _ = core.sgm_match(left, right, num_disparities=10, lr_check=1.0)  # "full" computes it anyway
    assert r0 is None and r3 is None and r1 is not None and r4 is not None
    np.testing.assert_array_equal(r1, r4)
    np.testing.assert_array_equal(d0, d1)
    np.testing.assert_array_equal(d2, d3)
    np.testing.assert_array_equal(r1, r2)
    assert r1.dtype == np.float32 and r1.shape == left.shape


def test_sad_and_four_paths_run_end_to_end():
    left, right = _pair(42, h=20, w=40, shift=4, noise=0)
    for cost in ("census", "sad"):
        for paths in (4, 8):
            pen = dict(p1=P1, p2=P2) if cost == "census" else dict(p1=200, p2=800)
            d, dr, _ = core.sgm_match(left, right, cost=cost, paths=paths, num_disparities=8, **pen)
            inner = d[3:-3, 12:-6]
            assert np.nanmedian(inner) == pytest.approx(4, abs=0.5), (cost, paths)


# ---------------------------------------------------------------------------------------------
# borders


def test_left_border_uses_the_range_that_fits():
    left, right = _pair(50, h=16, w=48, shift=5, noise=0)
    d, dr, _ = core.sgm_match(left, right, num_disparities=24, lr_check=None, return_right=True)
    x = np.arange(48)
    # never a disparity whose match lies left of the right image, and no blanket NaN band
    assert np.all(np.isnan(d) | (d <= x[None, :] + 0.5))
    assert np.isfinite(d[:, :24]).mean() > 0.9
    assert np.isfinite(d[:, 0]).all() and np.all(d[:, 0] <= 0.5)
    # right view: right pixel xr can only take disparities whose left pixel xr + d is inside
    assert np.all(np.isnan(dr) | (x[None, :] + dr <= 47))


def test_no_candidate_columns_are_nan():
    left, right = _pair(51, h=8, w=20)
    d, dr, _ = core.sgm_match(left, right, min_disparity=5, num_disparities=4, lr_check=None)
    assert np.isnan(d[:, :5]).all() and np.isfinite(d[:, 5:]).all()
    d, dr, _ = core.sgm_match(left, right, min_disparity=-6, num_disparities=4, lr_check=None)
    # x - d must be <= 19 with d <= -3: columns 17..19 have no candidate
    assert np.isnan(d[:, 17:]).all() and np.isfinite(d[:, :17]).all()


# ---------------------------------------------------------------------------------------------
# synthetic pairs with known disparity


@pytest.mark.parametrize("cost", ["census", "sad", "census+grad"])
@pytest.mark.parametrize("disparity", [0, 7, 13])
def test_constant_disparity_recovered_exactly(cost, disparity):
    tex = _textured(40, 120, seed=disparity)
    left = np.round(tex).astype(np.uint8)
    right = np.round(_sample_rows(tex, np.arange(120)[None, :].repeat(40, 0) + disparity)).astype(np.uint8)
    p = dict(p1=P1, p2=P2) if cost != "sad" else dict(p1=200, p2=800)
    d, _, _ = core.sgm_match(left, right, cost=cost, num_disparities=32, lr_check=1.0, **p)
    inner = d[5:-5, 32:-8]
    assert np.isfinite(inner).all()
    np.testing.assert_array_equal(np.round(inner), disparity)
    assert np.abs(inner - disparity).mean() < 0.1


def test_step_disparity_recovered_in_the_interior():
    h, w = 48, 140
    tex = _textured(h, w + 40, seed=7)
    d_true = np.where(np.arange(w) < 70, 6.0, 14.0)[None, :].repeat(h, 0)
    # left pixel x shows the scene point seen at right pixel x - d: build the right image from that
    left = np.round(tex[:, :w]).astype(np.uint8)
    right_f = np.zeros((h, w))
    for y in range(h):
        xs = np.arange(w)
        for x in range(w):
            xr = x - int(d_true[y, x])
            if 0 <= xr < w:
                right_f[y, xr] = tex[y, x]
    # fill right-image pixels no left pixel maps to (occluded in the left view) with other texture
    holes = right_f == 0
    right_f[holes] = tex[:, 20:20 + w][holes]
    right = np.round(right_f).astype(np.uint8)
    d, _, _ = core.sgm_match(left, right, num_disparities=32, p1=P1, p2=P2, lr_check=1.0)
    interior = np.zeros((h, w), bool)
    interior[5:-5, 24:62] = True
    interior[5:-5, 84:-6] = True
    got = d[interior]
    assert np.isfinite(got).mean() > 0.99
    np.testing.assert_array_equal(np.round(got[np.isfinite(got)]), d_true[interior][np.isfinite(got)])


@pytest.mark.parametrize("cost, p1, p2", [("census", 20, 80), ("sad", 200, 800)])
def test_slanted_plane_subpixel_error_below_a_tenth_of_a_pixel(cost, p1, p2):
    h, w = 60, 200
    tex = _textured(h, w, seed=11)
    x = np.arange(w, dtype=np.float64)[None, :].repeat(h, 0)
    d_true = 8.0 + 0.1 * x  # left-view disparity of a slanted plane: 8 .. 28 px
    # right pixel xr sees the left pixel x with x - d(x) = xr  =>  x = (xr + 8) / 0.9
    right = np.round(_sample_rows(tex, (x + 8.0) / 0.9)).astype(np.uint8)
    left = np.round(tex).astype(np.uint8)
    kw = dict(cost=cost, num_disparities=48, p1=p1, p2=p2, lr_check=1.0)
    d, _, _ = core.sgm_match(left, right, subpixel=True, **kw)
    inner = (slice(6, -6), slice(50, -10))
    err = np.abs(d[inner] - d_true[inner])
    assert np.isfinite(err).mean() > 0.99
    assert np.nanmean(err) < 0.1  # measured: census 0.076, SAD 0.080
    d0, _, _ = core.sgm_match(left, right, subpixel=False, **kw)
    assert np.nanmean(np.abs(d0[inner] - d_true[inner])) > 0.2  # integer disparities: about 0.25


# ---------------------------------------------------------------------------------------------
# parameters, errors, memory


def test_bad_parameters_raise_value_errors():
    left, right = _pair(60)
    with pytest.raises(ValueError, match="paths"):
        core.sgm_match(left, right, paths=5)
    with pytest.raises(ValueError, match="cost"):
        core.sgm_match(left, right, cost="ncc")
    with pytest.raises(ValueError, match="p2"):
        core.sgm_match(left, right, p1=10, p2=5000)
    with pytest.raises(ValueError, match="p1"):
        core.check_penalties("census", 5, (9, 7), 50, 20)
    with pytest.raises(ValueError, match="cost"):
        core.cost_volume(left, right, cost="zncc")
    with pytest.raises(ValueError, match="lr_mode"):
        core.sgm_match(left, right, lr_mode="strict")
    with pytest.raises(ValueError, match="right"):
        core.sgm_match(left, right[:, :-1])
    with pytest.raises(ValueError, match="left"):
        core.sgm_match(left.astype(np.float32), right)
    with pytest.raises(ValueError, match="left"):
        core.sgm_match(np.asfortranarray(np.repeat(left, 2, axis=0)), np.repeat(right, 2, axis=0))
    with pytest.raises(ValueError, match="num_disparities"):
        core.sgm_match(left, right, num_disparities=0)


@pytest.mark.parametrize("cost", ["census", "sad"])
def test_largest_allowed_p2_is_accepted_and_next_refused(cost):
    limit = None
    for p2 in range(100, 20000, 1):
        try:
            core.check_penalties(cost, 5, (9, 7), 1, p2)
        except ValueError:
            limit = p2 - 1
            break
    if cost == "census":
        assert limit == 1344
    else:
        assert limit is None  # SAD scales with the penalties: any p2 fits


def test_memory_bytes_counts_the_sum_volume():
    H, W, D = 375, 1242, 128
    n = core.memory_bytes(H, W, D)
    assert 2 * H * W * D < n < 3 * H * W * D
    assert core.memory_bytes(H, W, 2 * D) > n
    assert core.memory_bytes(H, W, D, cost="sad", block_size=7) > 2 * H * W * D


@pytest.mark.parametrize("paths, cost", [(3, "census+grad"), (3, "sad"), (8, "census+grad"), (4, "census")])
def test_memory_bytes_is_not_below_what_a_call_allocates(paths, cost):
    """The estimate the matcher checks before allocating covers the kernels' real peak (tracemalloc)."""
    import tracemalloc

    left, right = _pair(62, h=120, w=150)
    p = dict(p1=28, p2=112) if cost != "sad" else dict(p1=200, p2=800)
    kw = dict(cost=cost, num_disparities=48, paths=paths, threads=2, **p)
    core.sgm_match(left, right, **kw)  # compiled, pool started
    tracemalloc.start()
    try:
        core.sgm_match(left, right, **kw)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    estimate = core.memory_bytes(120, 150, 48, paths=paths, cost=cost, threads=2)
    assert peak <= estimate, (peak, estimate)
    if paths == 3:  # no sum volume: well below one H x W x D int16 volume
        assert estimate < 2 * 120 * 150 * 48


def test_workspace_is_reused_and_gives_identical_results():
    left, right = _pair(61, h=20, w=40)
    ws = core.Workspace()
    a = core.sgm_match(left, right, num_disparities=16, workspace=ws)[0]
    S_id = id(ws.S)
    b = core.sgm_match(left, right, num_disparities=16, workspace=ws)[0]
    assert id(ws.S) == S_id and ws.nbytes > 0
    c = core.sgm_match(left, right, num_disparities=8, workspace=ws)[0]  # other size: new buffers
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(c, core.sgm_match(left, right, num_disparities=8)[0])
    ws.release()
    assert ws.nbytes == 0


@settings(max_examples=180, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(h=st.integers(1, 9), w=st.integers(1, 24), dmin=st.integers(-6, 6), D=st.integers(1, 20),
       cost=st.sampled_from(["census", "sad", "census+grad"]), paths=st.sampled_from([3, 4, 8]),
       seed=st.integers(0, 2**16),
       lr=st.sampled_from([None, 0.0, 1.0]), uniq=st.sampled_from([0.0, 0.15]))
def test_random_shapes_give_well_formed_results(h, w, dmin, D, cost, paths, seed, lr, uniq):
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, (h, w), dtype=np.uint8)
    right = rng.integers(0, 256, (h, w), dtype=np.uint8)
    p = dict(p1=P1, p2=P2) if cost != "sad" else dict(p1=200, p2=800)
    d, dr, _ = core.sgm_match(left, right, cost=cost, min_disparity=dmin, num_disparities=D, paths=paths,
                              lr_check=lr, uniqueness=uniq, **p)
    assert d.shape == (h, w) and d.dtype == np.float32
    assert (dr is None) == (lr is None) and (dr is None or dr.shape == (h, w))
    ok = np.isfinite(d)
    assert not np.isinf(d).any()
    assert np.all(d[ok] >= dmin - 0.5) and np.all(d[ok] <= dmin + D - 1 + 0.5)
    x = np.arange(w)[None, :].repeat(h, 0)
    assert np.all(x[ok] - np.round(d[ok]) >= -0.5) and np.all(x[ok] - np.round(d[ok]) <= w - 0.5)
    if lr is None and uniq == 0.0:
        S = core.sum_volume(left, right, cost=cost, min_disparity=dmin, num_disparities=D,
                            path_mask=core.PATH_MASKS[paths], **p)
        want, _ = ref.select_reference(S, dmin, uniqueness=0.0, lr_check=None)
        np.testing.assert_array_equal(d, want)


def test_kernels_import_nothing_else_from_the_project():
    """The kernels stand alone: params and matcher import them, never the other way round."""
    for path in sorted(Path(core.__file__).parent.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ImportFrom):
                assert node.level == 0, f"{path.name}: relative import"
                names = [node.module or ""]
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            else:
                continue
            for name in names:
                ours = name.split(".")[0] in ("stereo_classic", "calib", "detectors", "benchmarks")
                assert not ours or name.startswith("stereo_classic.matching._kernels"), f"{path.name} imports {name}"


# --------------------------------------------------------------------------------------------------
# the parallel decomposition: stripes fixed by the image height, any number of threads
# --------------------------------------------------------------------------------------------------
def test_stripes_cover_every_row_once_and_depend_on_the_height_only():
    for h in (1, 2, 47, 48, 73, 375, 480, 1080):
        bands = core.stripes(h)
        assert bands[0][0] == 0 and bands[-1][1] == h
        assert all(a[1] == b[0] for a, b in zip(bands, bands[1:]))
        sizes = [y1 - y0 for y0, y1 in bands]
        assert max(sizes) - min(sizes) <= 1 and (h < core.STRIPE_ROWS or min(sizes) >= core.STRIPE_ROWS // 2)


@pytest.mark.parametrize("paths", [3, 4, 8])
def test_same_output_for_every_thread_count(paths, monkeypatch):
    """The stripes are fixed by the height: 1, 2, 3, 5 and 8 threads give bit-identical results (workers are
    capped at the usable CPUs: the cap is lifted here so that 3, 5 and 8 workers really run on a 2-core machine)."""
    monkeypatch.setattr(core, "usable_cpus", lambda: 64)
    tex = _textured(150, 90, seed=3)
    left = np.round(tex).astype(np.uint8)
    right = np.round(_sample_rows(tex, np.arange(90)[None, :].repeat(150, 0) + 6)).astype(np.uint8)
    assert len(core.stripes(150)) >= 3
    first = None
    for threads in (1, 2, 3, 5, 8):
        d, dr, t = core.sgm_match(left, right, cost="census+grad", num_disparities=16, p1=28, p2=112, paths=paths,
                                  uniqueness=0.05, lr_check=1.0, threads=threads, return_right=True)
        got = (d, dr, t["n_failed_lr"], t["n_failed_uniqueness"])
        if first is None:
            first = got
            continue
        np.testing.assert_array_equal(got[0], first[0])
        np.testing.assert_array_equal(got[1], first[1])
        assert got[2:] == first[2:]


@pytest.mark.parametrize("cost", ["census+grad", "sad", "census"])
def test_warm_up_costs_reused_down_a_run_of_stripes_change_nothing(cost, monkeypatch):
    """A worker that ran the stripe above reads the warm-up rows' costs it made instead of making them again (and
    carries the cost state on): the same maps as when every stripe makes its own, for any thread count."""
    monkeypatch.setattr(core, "usable_cpus", lambda: 64)
    tex = _textured(400, 70, seed=5)
    left = np.round(tex).astype(np.uint8)
    right = np.round(_sample_rows(tex, np.arange(70)[None, :].repeat(400, 0) + 4)).astype(np.uint8)
    assert len(core.stripes(400)) >= 8
    kw = dict(cost=cost, num_disparities=16, p1=28 if cost != "sad" else 200, p2=112 if cost != "sad" else 800,
              paths=3, uniqueness=0.05, lr_check=1.0, return_right=True)
    chained = core.run_chained
    calls = []

    def counting(n, workers, fn, **kw):
        chained(n, workers, lambda t, i, after: (calls.append(after), fn(t, i, after)), **kw)

    monkeypatch.setattr(core, "run_chained", counting)
    runs = [core.sgm_match(left, right, threads=threads, **kw) for threads in (1, 2, 3, 5, 8)]
    assert sum(calls) >= 7  # the 1-thread call alone reuses the costs at every border
    monkeypatch.setattr(core, "run_chained",
                        lambda n, workers, fn, **kw: chained(n, workers, lambda t, i, after: fn(t, i, False), **kw))
    fresh = core.sgm_match(left, right, threads=1, **kw)
    for d, dr, t in runs:
        np.testing.assert_array_equal(d, fresh[0])
        np.testing.assert_array_equal(dr, fresh[1])
        assert (t["n_failed_lr"], t["n_failed_uniqueness"]) == (fresh[2]["n_failed_lr"], fresh[2]["n_failed_uniqueness"])


def test_run_chained_runs_every_item_once_down_runs():
    import threading

    seen, lock = [], threading.Lock()
    for workers in (1, 2, 3, 8):
        seen.clear()
        core.run_chained(11, workers, lambda t, i, after: (lock.acquire(), seen.append((t, i, after)), lock.release()))
        assert sorted(i for _, i, _ in seen) == list(range(11))
        last: dict[int, int] = {}
        for t, i, after in seen:  # after is true exactly when the same worker's previous item was i - 1
            assert after == (last.get(t) == i - 1)
            last[t] = i


def test_run_chained_follows_every_item_once_after_it():
    """``follow(t, i)`` runs once per item, after ``fn`` has done it (one worker: right after it), on any worker."""
    import threading

    lock = threading.Lock()
    for workers in (1, 2, 3, 8):
        events: list[tuple[str, int]] = []

        def log(kind, i):
            with lock:
                events.append((kind, i))

        core.run_chained(11, workers, lambda t, i, after: log("item", i), follow=lambda t, i: log("follow", i))
        assert sorted(i for kind, i in events if kind == "follow") == list(range(11))
        for i in range(11):
            assert events.index(("item", i)) < events.index(("follow", i))
        if workers == 1:
            assert events == [(kind, i) for i in range(11) for kind in ("item", "follow")]


@pytest.mark.parametrize("where", ["item", "follow"])
def test_run_chained_raises_an_error_of_any_worker_without_hanging(where):
    """A worker's error reaches the caller and the other workers stop (none waits for follow-ups that never come)."""
    import threading
    import time

    def item(t, i, after):
        if where == "item" and i == 7:
            raise RuntimeError("item 7")
        time.sleep(0.002)

    def follow(t, i):
        if where == "follow" and i == 2:
            raise RuntimeError("follow 2")

    for workers in (1, 2, 4):
        caught: list[str] = []

        def run():
            try:
                core.run_chained(11, workers, item, follow=follow)
            except RuntimeError as err:
                caught.append(str(err))

        runner = threading.Thread(target=run, daemon=True)
        runner.start()
        runner.join(20)
        assert not runner.is_alive() and caught == ["item 7" if where == "item" else "follow 2"]


@pytest.mark.parametrize("threads", [1, 3])
def test_horizontal_paths_are_exact_across_stripes(threads):
    """Left and right paths never cross a row: on a tall image cut into stripes they equal the reference."""
    left, right = _pair(32, h=130, w=24, shift=2)
    assert len(core.stripes(130)) >= 2
    C = ref.cost_volume_reference(left, right, num_disparities=8, p2=P2)
    want = ref.sum_reference(C, 0x11, P1, P2)
    got = core.sum_volume(left, right, path_mask=0x11, threads=threads, num_disparities=8, p1=P1, p2=P2)
    np.testing.assert_array_equal(got, want)


def test_usable_cpus_honours_the_affinity_mask(monkeypatch):
    n = core.usable_cpus()
    assert 1 <= n <= len(os.sched_getaffinity(0))
    from stereo_classic.matching._kernels import workers

    reads = []
    monkeypatch.setattr(workers.os, "sched_getaffinity", lambda pid: reads.append(pid) or {0})
    monkeypatch.setattr(workers, "_cpus_read", [n, time.monotonic()])  # read just now: kept
    assert core.usable_cpus() == n and reads == []
    monkeypatch.setattr(workers, "_cpus_read", [n, time.monotonic() - workers.CPUS_RECHECK_S])  # long enough ago
    assert core.usable_cpus() == 1 and reads == [0]
    assert core.usable_cpus() == 1 and reads == [0]


@pytest.mark.parametrize("paths, kernel", [(3, "three_path_stripe"), (8, "sgm_pass")])
def test_first_compile_note_looks_at_the_kernel_the_call_runs(paths, kernel, monkeypatch, caplog, tmp_path):
    """The "compiling once" note is said when the cache of the kernel this call runs is missing, and only then."""
    import logging

    cached, missing = tmp_path / "cached.nbi", tmp_path / "missing.nbi"
    cached.write_bytes(b"")
    other = "sgm_pass" if kernel == "three_path_stripe" else "three_path_stripe"
    for name, index in ((kernel, missing), (other, cached)):
        monkeypatch.setattr(getattr(core, name)._cache._cache_file, "_index_path", str(index))
    for index, said in ((missing, True), (cached, False)):
        monkeypatch.setattr(getattr(core, kernel)._cache._cache_file, "_index_path", str(index))
        monkeypatch.setattr(core, "_compile_note_done", False)
        caplog.clear()
        with caplog.at_level(logging.INFO, logger="stereo_classic"):
            core._note_first_compile(paths)
        assert ("compiling the stereo kernels once" in caplog.text) == said


@pytest.mark.parametrize("paths", [3, 8])
@pytest.mark.parametrize("cost", ["census+grad", "sad"])
@pytest.mark.parametrize("lr_mode", ["full", "opencv"])
def test_disparity_padding_changes_nothing(paths, cost, lr_mode, monkeypatch):
    """The kernels hold whole blocks of disparities per pixel (``padded_disparities``); the padding past the range
    never wins and never changes a path value in range: the left and right views and the rejection counts are
    those of buffers exactly as wide as the range, for ranges below, at and between the blocks, at either sign of
    the smallest disparity."""
    tex = _textured(60, 150, seed=11)
    left = np.round(tex).astype(np.uint8)
    right = np.round(_sample_rows(tex, np.arange(150)[None, :].repeat(60, 0) + 9)).astype(np.uint8)
    pen = dict(p1=28, p2=112) if cost != "sad" else dict(p1=200, p2=800)
    for dmin, n in ((0, 5), (-4, 40), (3, 64), (0, 70), (-10, 100), (-20, 8)):
        padded = core.padded_disparities(n, paths)
        block = core.ONE_SWEEP_BLOCK if paths == 3 else core.DISPARITY_BLOCK
        assert padded % block == 0 and padded >= max(n, core.MIN_DISPARITIES_ONE_SWEEP if paths == 3 else block)
        kw = dict(cost=cost, min_disparity=dmin, num_disparities=n, paths=paths, uniqueness=0.05, lr_check=1.0,
                  lr_mode=lr_mode, return_right=True, threads=2, **pen)
        d, dr, t = core.sgm_match(left, right, **kw)
        with monkeypatch.context() as m:
            m.setattr(core, "DISPARITY_BLOCK", 1)
            m.setattr(core, "ONE_SWEEP_BLOCK", 1)
            m.setattr(core, "MIN_DISPARITIES_ONE_SWEEP", 1)
            assert core.padded_disparities(n, paths) == n
            d1, dr1, t1 = core.sgm_match(left, right, **kw)
        np.testing.assert_array_equal(d, d1)
        np.testing.assert_array_equal(dr, dr1)
        assert (t["n_failed_lr"], t["n_failed_uniqueness"]) == (t1["n_failed_lr"], t1["n_failed_uniqueness"])
        assert np.isfinite(d).any() and np.nanmax(d) <= dmin + n - 1 and np.nanmin(d) >= dmin


def test_disparity_tag_carries_the_buffers_disparities():
    """The kernels read D from a tag whose numba type holds it (compiled once per D): the tag gives back every D,
    whole blocks or not, and each worker's buffers carry the tag of their own D."""
    from numba import njit

    from stereo_classic.matching._kernels.rowpass import row_pass_buffers
    from stereo_classic.matching._kernels.tags import disparity_tag, tag_disparities

    read = njit(lambda tag: tag_disparities(tag))
    for D in (1, 8, 31, 32, 64, 70, 96, 128, 256, 1000):
        tag = disparity_tag(D)
        assert read(tag) == D and len(tag[0]) == D // 32 and len(tag[1]) == D % 32
    for D in (64, 96):
        assert read(row_pass_buffers(10, 40, D).tag) == D
        assert read(core._row_cost_buffers(40, D, 2, 2).tag) == D
    for bad in (0, -3):
        with pytest.raises(ValueError, match="`D` must be"):
            disparity_tag(bad)


def test_row_pass_bytes_is_what_the_buffers_take():
    """``row_pass_bytes`` (``memory_bytes``'s term for the one-sweep kernel's buffers) is exactly their size."""
    from stereo_classic.matching._kernels.rowpass import row_pass_buffers, row_pass_bytes

    for H, W, D, warm in ((480, 640, 64, 16), (375, 1242, 128, 16), (10, 40, 96, 0)):
        buffers = row_pass_buffers(H, W, D, warm)
        assert row_pass_bytes(H, W, D, warm) == sum(a.nbytes for a in buffers if isinstance(a, np.ndarray))


def test_buffers_start_on_a_cache_line():
    """The row buffers, the cost state and the workspace's arrays start on a 64-byte boundary, and so does every
    path slot's first disparity (element 1 of a slot of ``slot_size(D)``), for whole and padded ranges."""
    from stereo_classic.matching._kernels.aligned import ALIGNMENT, aligned_empty, aligned_zeros
    from stereo_classic.matching._kernels.rowpass import row_pass_buffers, slot_size

    def on_line(a: np.ndarray, element: int = 0) -> bool:
        return (a.ctypes.data + element * a.itemsize) % ALIGNMENT == 0

    for D in (64, 96, 128, 160):
        E = slot_size(D)
        assert E >= D + 2 and E * 2 % ALIGNMENT == 0
        b = row_pass_buffers(30, 77, D, warm_rows=16)
        for name in ("costs", "srow", "row_min", "right_sums", "right_k"):
            assert on_line(getattr(b, name)), name
        for name in ("path_v", "path_h", "path_r"):
            P = getattr(b, name).reshape(-1, E)
            assert all(on_line(P, s * E + 1) for s in range(P.shape[0])), name
            assert (P[:, 0] == P[0, 0]).all() and (P[:, D + 1] == P[0, 0]).all() and P[0, 0] != 0  # sentinels
            assert (P[:, 1:D + 1] == 0).all()
        c = core._row_cost_buffers(77, D, 2, 2)  # census + gradient
        for name in ("colsum", "hsum", "floor", "rrev", "srev"):
            assert on_line(getattr(c, name)), name
    ws = core.Workspace()
    assert on_line(ws.scratch("x", (7, 9), np.float32)) and on_line(core.scratch_allocator(None)("y", (5,), np.int16))
    for dtype, lead in ((np.int16, 0), (np.int16, 1), (np.int16, 31), (np.uint8, 63), (np.float64, 7)):
        a = aligned_zeros((3, 11), dtype, lead=lead)
        assert a.shape == (3, 11) and a.dtype == dtype and a.flags.c_contiguous and not a.any()
        assert on_line(a, lead) and aligned_empty(5, dtype).shape == (5,)
    for bad in (-1, 32):
        with pytest.raises(ValueError, match="`lead`"):
            aligned_empty(4, np.int16, lead=bad)
    with pytest.raises(ValueError, match="`dtype`"):
        aligned_empty(4, np.dtype("V3"))


@pytest.mark.parametrize("paths", [3, 8])
def test_output_does_not_depend_on_where_the_buffers_start(paths, monkeypatch):
    """Where the buffers start is a matter of speed only: with every buffer moved 16 bytes off its cache line (path
    slots included), both views and the counts are the same bit for bit."""
    from stereo_classic.matching._kernels import aligned, rowpass

    tex = _textured(70, 160, seed=5)
    left = np.round(tex).astype(np.uint8)
    right = np.round(_sample_rows(tex, np.arange(160)[None, :].repeat(70, 0) + 7)).astype(np.uint8)
    kw = dict(cost="census+grad", num_disparities=40, paths=paths, uniqueness=0.05, lr_check=1.0, return_right=True,
              threads=2, p1=28, p2=112)
    d, dr, t = core.sgm_match(left, right, **kw)
    made = []

    def off_line(shape, dtype, lead=0):
        made.append(shape)
        a = aligned.aligned_empty(np.prod(shape, dtype=np.int64) * np.dtype(dtype).itemsize + 16, np.uint8)
        out = a[16:].view(dtype).reshape(shape)
        assert (out.ctypes.data + lead * out.itemsize) % aligned.ALIGNMENT != 0
        return out

    def off_line_zeros(shape, dtype, lead=0):
        out = off_line(shape, dtype, lead)
        out[...] = 0
        return out

    for module in (core, rowpass):
        monkeypatch.setattr(module, "aligned_empty", off_line)
        monkeypatch.setattr(module, "aligned_zeros", off_line_zeros)
    d1, dr1, t1 = core.sgm_match(left, right, **kw)
    assert len(made) >= 10  # the row buffers, the cost state and the cost images
    np.testing.assert_array_equal(d, d1)
    np.testing.assert_array_equal(dr, dr1)
    assert t["n_failed_lr"] == t1["n_failed_lr"] and np.isfinite(d).mean() > 0.5
