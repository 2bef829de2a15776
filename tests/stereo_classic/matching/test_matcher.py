"""The matcher (stereo_classic.matching.matcher): compute_disparity, StereoMatcher, DisparityMap, memory budget."""

from __future__ import annotations

import dataclasses
import re

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stereo_classic.matching import matcher as matcher_mod
from stereo_classic.matching._kernels import core as kernels
from stereo_classic.matching.matcher import (
    DisparityMap,
    MemoryBudgetError,
    StereoInputError,
    StereoMatcher,
    compute_disparity,
    estimate_memory,
    to_gray_uint8,
)
from stereo_classic.matching.params import MEMORY_LIMIT_ENV, SGMParams


# --------------------------------------------------------------------------------------------------
# synthetic pairs
# --------------------------------------------------------------------------------------------------
def _texture(shape, seed=0, smooth=1.0):
    rng = np.random.default_rng(seed)
    img = rng.uniform(0, 255, shape).astype(np.float32)
    if smooth > 0:
        img = cv2.GaussianBlur(img, (0, 0), smooth)
        img = (img - img.min()) / max(1e-6, float(img.max() - img.min())) * 255
    return img


def _warp_right(left_f, disparity):
    """Right image such that right(x - d(x, y)) = left(x, y) for a smooth d, by sampling left at x + d_r."""
    h, w = left_f.shape
    # right(xr) = left(xr + d) with d evaluated at xr + d; iterate the fixed point (d varies slowly)
    xs = np.tile(np.arange(w, dtype=np.float32), (h, 1))
    ys = np.repeat(np.arange(h, dtype=np.float32)[:, None], w, 1)
    xl = xs.copy()
    for _ in range(20):
        d = cv2.remap(disparity.astype(np.float32), xl, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        xl = xs + d
    return cv2.remap(left_f, xl, ys, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)


def _shift_pair(shape=(48, 96), shift=7, seed=0):
    right = np.random.default_rng(seed).integers(0, 256, shape, dtype=np.uint8)
    left = np.roll(right, shift, axis=1)
    return left, right


# --------------------------------------------------------------------------------------------------
# compute_disparity: smoke, dtypes, synthetic accuracy
# --------------------------------------------------------------------------------------------------
class TestComputeDisparity:
    def test_smoke_constant_shift(self):
        left, right = _shift_pair(shift=7)
        dmap = compute_disparity(left, right, num_disparities=16, subpixel=False)
        assert isinstance(dmap, DisparityMap)
        assert dmap.disparity.shape == left.shape and dmap.disparity.dtype == np.float32
        assert not np.isinf(dmap.disparity).any()
        interior = dmap.disparity[6:-6, 20:-6]
        assert np.isfinite(interior).mean() > 0.95
        np.testing.assert_array_equal(interior[np.isfinite(interior)], 7.0)
        assert set(dmap.timings_ms) >= {"prepare", "postprocess", "total"}
        assert dmap.timings_ms["total"] >= dmap.timings_ms["prepare"]
        v = dmap.validity
        assert v["pixels"] == left.size and v["valid"] == np.isfinite(dmap.filled_disparity).sum()
        assert 0.0 < dmap.valid_fraction <= 1.0 and dmap.valid_fraction == pytest.approx((v["valid"] - v["filled"]) / left.size)
        assert v["border"] == 15 * left.shape[0]  # columns 0..14 cannot hold the full range 0..15
        # columns 0..6 reach fewer than 16 / 2 disparities: never measured (filled from the background at most); the
        # true disparity 7 is out of reach for columns 0..6, so most of their winners lie outside the right image
        assert 0 <= v["short_range"] <= 7 * left.shape[0] and np.isnan(dmap.disparity[:, :7]).all()
        assert 0 < v["outside"] <= 7 * left.shape[0]
        assert (v["unknown_matcher"] + v["short_range"] + v["speckle_removed"] + v["valid"] - v["filled"]
                == left.size)

    def test_params_object_and_overrides(self):
        left, right = _shift_pair()
        params = SGMParams(num_disparities=16, lr_check=None)
        dmap = compute_disparity(left, right, params, speckle_size=0)
        assert dmap.params == params.replace(speckle_size=0)
        assert dmap.disparity_right is None or dmap.disparity_right.shape == left.shape
        with_lr = compute_disparity(left, right, params.replace(lr_check=1.0))
        assert with_lr.disparity_right is not None and with_lr.disparity_right.shape == left.shape
        asked = compute_disparity(left, right, params, right_view=True).disparity_right
        assert asked is not None and np.nanmedian(asked[:, 8:-24]) == 7.0  # right view: same disparity, by x_right
        lenient = compute_disparity(left, right, params.replace(lr_check=1.0, lr_mode="OpenCV"))
        assert lenient.params.lr_mode == "opencv" and lenient.valid_fraction >= with_lr.valid_fraction

    @pytest.mark.parametrize("dtype, scale", [(np.uint8, 1), (np.uint16, 257), (np.uint16, 16), (np.float32, 1 / 255),
                                              (np.float64, 1.0), (np.float32, 1000.0)])
    @pytest.mark.parametrize("colour", [False, True])
    def test_dtypes_and_colour(self, dtype, scale, colour):
        left, right = _shift_pair(shift=5, seed=3)
        if colour:
            left, right = (np.dstack([im, im, im]) for im in (left, right))
        args = [(im.astype(np.float64) * scale).astype(dtype) for im in (left, right)]
        dmap = compute_disparity(*args, num_disparities=16)
        interior = dmap.disparity[6:-6, 20:-6]
        assert np.isfinite(interior).mean() > 0.9
        assert np.nanmedian(np.abs(interior - 5.0)) < 0.05

    def test_non_native_byte_order(self):
        left, right = _shift_pair(shift=5)
        big = [im.astype(">f4") for im in (left, right)]
        np.testing.assert_array_equal(compute_disparity(*big, num_disparities=16).disparity,
                                      compute_disparity(left.astype(np.float32), right.astype(np.float32),
                                                        num_disparities=16).disparity)

    def test_grey_conversion_shares_one_mapping(self):
        rng = np.random.default_rng(1)
        a = rng.uniform(100, 1000, (20, 30))
        ga, gb = to_gray_uint8(a, a * 0.5 + 100)  # darker right camera must stay darker
        assert ga.dtype == np.uint8 and ga.flags.c_contiguous and gb.shape == (20, 30)
        assert ga.mean() > gb.mean() + 30  # separate stretching would make both means ~128
        # uint8 grey is passed through without a copy
        g = rng.integers(0, 256, (10, 12), dtype=np.uint8)
        assert to_gray_uint8(g, g)[0] is g
        # colour uint8 uses OpenCV's BGR weights
        c = rng.integers(0, 256, (10, 12, 3), dtype=np.uint8)
        np.testing.assert_array_equal(to_gray_uint8(c, c)[0], cv2.cvtColor(c, cv2.COLOR_BGR2GRAY))
        # extreme but finite floats and constant images do not overflow or divide by zero
        huge = np.full((8, 8), 1e308)
        huge[0, 0] = -1e308
        assert to_gray_uint8(huge, huge)[0].dtype == np.uint8
        z = np.zeros((8, 8), np.float32)
        assert not to_gray_uint8(z, z)[0].any()

    @pytest.mark.parametrize("left, right, needle", [
        (np.zeros((8, 8), np.uint8), np.zeros((8, 8), np.float64), "same dtype"),
        (np.zeros((8, 8), np.uint8), np.zeros((8, 9), np.uint8), "same shape"),
        (np.full((8, 8), np.nan), np.zeros((8, 8)), "`left` must hold finite values, got 64 NaN"),
        (np.zeros((8, 8), np.float32), np.full((8, 8), np.inf, np.float32), "`right` must hold finite"),
        (np.zeros((8, 8), np.int32), np.zeros((8, 8), np.int32), "dtype uint8, uint16"),
        (np.zeros((8, 8, 4), np.uint8), np.zeros((8, 8, 4), np.uint8), "grey (H, W) or colour"),
        ("left.png", np.zeros((8, 8), np.uint8), "read_image"),
    ])
    def test_grey_conversion_checks_the_pair(self, left, right, needle):
        with pytest.raises(StereoInputError, match=re.escape(needle)):
            to_gray_uint8(left, right)

    def test_stereo_matcher_reuses_checks(self, monkeypatch):
        left, right = _shift_pair()
        m = StereoMatcher(num_disparities=16)
        assert m.params.num_disparities == 16 and "num_disparities=16" in repr(m)
        first = m.compute(left, right)
        np.testing.assert_array_equal(first.disparity, compute_disparity(left, right, num_disparities=16).disparity)
        calls = []
        monkeypatch.setattr(matcher_mod, "_check_memory", lambda *a: calls.append(a))
        second = m.compute(left, right)
        assert calls == []  # same size: memory already checked
        np.testing.assert_array_equal(first.disparity, second.disparity)
        m.compute(left[:40], right[:40])
        assert len(calls) == 1

    @pytest.mark.parametrize("lr_check, uniqueness", [(None, 0), (1.0, 0), (None, 10), (1.0, 10)])
    def test_validity_split(self, lr_check, uniqueness):
        left, right = _shift_pair(shift=9, seed=11)
        left[:, 50:60] = 128  # a flat patch: ambiguous, some pixels fail the filters
        dmap = compute_disparity(left, right, min_disparity=3, num_disparities=16, lr_check=lr_check,
                                 uniqueness=uniqueness, speckle_size=0, fill_holes=False, border_reach=0.0)
        v = dmap.validity
        assert v["no_candidate"] == 3 * left.shape[0]  # columns 0..2 cannot reach disparity >= 3
        assert np.isnan(dmap.disparity[:, :3]).all()
        assert v["unknown_matcher"] == np.isnan(dmap.disparity).sum()
        if lr_check is None:
            assert v["failed_lr"] == 0
        if uniqueness == 0:
            assert v["failed_uniqueness"] == 0
        # the kernels count both filters exactly, also when both are on
        assert v["no_candidate"] + v["failed_lr"] + v["failed_uniqueness"] + v["outside"] == v["unknown_matcher"]
        assert (v["failed_lr"] > 0) == (lr_check is not None)
        assert (v["failed_uniqueness"] > 0) == (uniqueness > 0)

    def test_stereo_matcher_reuses_kernel_buffers(self):
        left, right = _shift_pair(seed=4)
        m = StereoMatcher(num_disparities=16)
        first = m.compute(left, right)
        workspace = m._workspace
        # the default (3 paths) keeps row buffers, at least the cost and sum rows of one worker
        assert workspace and workspace.nbytes >= 2 * 2 * left.shape[1] * 16
        kept = workspace.arrays()
        second = m.compute(left, right)
        # same size: reused, results unchanged and not shared
        assert all(a is b for a, b in zip(m._workspace.arrays(), kept)) and len(m._workspace.arrays()) == len(kept)
        np.testing.assert_array_equal(first.disparity, second.disparity)
        assert first.disparity is not second.disparity
        assert not any(np.shares_memory(first.disparity, a) for a in kept)
        other = m.compute(left[:, :80], right[:, :80])  # new size: new buffers, same answer as a fresh call
        np.testing.assert_array_equal(other.disparity,
                                      compute_disparity(left[:, :80], right[:, :80], num_disparities=16).disparity)
        np.testing.assert_array_equal(m.compute(left, right).disparity, first.disparity)
        m.release()
        assert m._workspace is None
        np.testing.assert_array_equal(m.compute(left, right).disparity, first.disparity)

    @pytest.mark.parametrize("post", [{}, dict(fill_holes=False), dict(speckle_size=0),
                                      dict(speckle_size=0, fill_holes=False), dict(lr_check=None)])
    def test_stereo_matcher_results_do_not_share_its_scratch_arrays(self, post):
        """The kernel's raw map and the post-processing temporaries live in the workspace: a result must stay as
        it was when the next frame is matched, and equal a fresh call's."""
        a, b = _shift_pair(seed=4, shift=5), _shift_pair(seed=5, shift=9)
        m = StereoMatcher(num_disparities=16, speckle_size=post.get("speckle_size", 20),
                          **{k: v for k, v in post.items() if k != "speckle_size"})
        first = m.compute(*a)
        kept = [first.disparity.copy(), None if first.filled is None else first.filled.copy()]
        second = m.compute(*b)
        np.testing.assert_array_equal(first.disparity, kept[0])
        if kept[1] is not None:
            np.testing.assert_array_equal(first.filled, kept[1])
        for res, pair in ((first, a), (second, b)):
            fresh = compute_disparity(*pair, m.params)
            np.testing.assert_array_equal(res.disparity, fresh.disparity)
            assert res.validity == fresh.validity
            for arr in (res.disparity, res.filled_disparity, res.filled, res.disparity_right):
                assert arr is None or not any(np.shares_memory(arr, w) for w in m._workspace.arrays())

    def test_stereo_matcher_threads(self):
        from concurrent.futures import ThreadPoolExecutor

        left, right = _shift_pair(seed=6)
        m = StereoMatcher(num_disparities=16, threads=1)
        expected = compute_disparity(left, right, num_disparities=16, threads=1).disparity
        with ThreadPoolExecutor(3) as pool:
            maps = list(pool.map(lambda _: m.compute(left, right), range(6)))
        for dmap in maps:
            np.testing.assert_array_equal(dmap.disparity, expected)

    def test_busy_shared_matcher_checks_memory_for_its_own_buffers(self, monkeypatch):
        import threading

        left, right = _shift_pair(seed=6)
        need = estimate_memory(left.shape, SGMParams(num_disparities=16, threads=1))
        m = StereoMatcher(num_disparities=16, threads=1, memory_limit=need + need // 2)  # one call fits, two do not
        expected = m.compute(left, right).disparity  # the size is checked (and remembered) once
        core = kernels
        inside, go_on = threading.Event(), threading.Event()
        real = core.sgm_match

        def held(*a, **kw):
            inside.set()
            assert go_on.wait(30)
            return real(*a, **kw)

        monkeypatch.setattr(core, "sgm_match", held)
        result = {}
        busy = threading.Thread(target=lambda: result.setdefault("map", m.compute(left, right)))
        busy.start()
        try:
            assert inside.wait(30)
            with pytest.raises(MemoryBudgetError, match="another thread's call on the same StereoMatcher"):
                m.compute(left, right)
        finally:
            go_on.set()
            busy.join(30)
        np.testing.assert_array_equal(result["map"].disparity, expected)
        # with room for both, the busy fallback works and gives the same answer
        roomy = StereoMatcher(num_disparities=16, threads=1, memory_limit=3 * need)
        inside.clear(), go_on.clear()
        busy = threading.Thread(target=lambda: result.update(map=roomy.compute(left, right)))
        busy.start()
        try:
            assert inside.wait(30)
            go_on.set()  # the second call goes through sgm_match too
            np.testing.assert_array_equal(roomy.compute(left, right).disparity, expected)
        finally:
            go_on.set()
            busy.join(30)

    @pytest.mark.parametrize("shape, dtype", [
        ((300, 400, 3), np.float64), ((300, 400, 3), np.uint16), ((300, 400), np.float64),
        ((300, 400, 3), np.float32), ((1200, 1000, 3), np.float32), ((300, 400, 3), np.uint8),
    ])
    def test_grey_conversion_stays_within_the_memory_estimate(self, shape, dtype):
        import tracemalloc

        rng = np.random.default_rng(2)
        a, b = (rng.uniform(0, 1000, shape).astype(dtype) for _ in range(2))
        to_gray_uint8(a[:8, :8], b[:8, :8])  # first-call allocations (imports, caches) out of the way
        params = SGMParams(num_disparities=16)
        pixels = shape[0] * shape[1]
        counted = estimate_memory(shape, params, dtype=dtype) - estimate_memory(shape, params) + 2 * pixels
        tracemalloc.start()
        try:
            base = tracemalloc.get_traced_memory()[0]
            to_gray_uint8(a, b)
            peak = tracemalloc.get_traced_memory()[1] - base
        finally:
            tracemalloc.stop()
        assert peak <= counted + 64 * 1024, (peak / pixels, counted / pixels)

    def test_fill_holes_option_makes_map_denser(self):
        left, right = _shift_pair(shift=9)
        sparse = compute_disparity(left, right, num_disparities=16, uniqueness=5, fill_holes=False)
        dense = compute_disparity(left, right, num_disparities=16, uniqueness=5, fill_holes=True)
        assert dense.validity["filled"] > 0
        assert dense.validity["valid"] == sparse.validity["valid"] + dense.validity["filled"]
        assert sparse.validity["filled"] == 0


    def test_median_filter_changes_the_measurements_only(self):
        """``median_filter``: the measured pixels take the lower median of their measured 3x3 neighbours (the
        numpy definition of tests/.../test_postprocess.py, on the map without it), the unknown ones stay unknown
        and the filled ones keep the fill's values, which read the measurements before the median."""
        from tests.stereo_classic.matching.test_postprocess import _median_reference

        left_f = _texture((80, 160), seed=3)
        yy, xx = np.mgrid[0:80, 0:160]
        disparity = (8 + 6 * xx / 160 + 3 * yy / 80).astype(np.float32)  # slanted: subpixel steps to smooth
        disparity[20:50, 60:100] += 5  # a nearer box: occlusions, holes for the fill
        right_f = _warp_right(left_f, disparity)
        left, right = np.clip(left_f, 0, 255).astype(np.uint8), np.clip(right_f, 0, 255).astype(np.uint8)
        for threads in (1, 2):
            off = compute_disparity(left, right, num_disparities=32, threads=threads)
            on = compute_disparity(left, right, num_disparities=32, threads=threads, median_filter=True)
            assert 0 < on.validity["filled"] == off.validity["filled"] and on.validity == off.validity
            np.testing.assert_array_equal(np.isnan(on.disparity), np.isnan(off.disparity))
            np.testing.assert_array_equal(on.filled, off.filled)
            np.testing.assert_array_equal(on.filled_disparity[on.filled], off.filled_disparity[off.filled])
            np.testing.assert_array_equal(on.disparity, _median_reference(off.disparity, np.zeros(left.shape, bool)))
            assert not np.array_equal(on.disparity, off.disparity, equal_nan=True)


class TestSyntheticAccuracy:
    """Known-disparity pairs through the public API."""

    @pytest.mark.parametrize("cost", ["census", "sad"])
    @pytest.mark.parametrize("min_disparity, shift", [(0, 11), (-8, -5), (4, 20)])
    def test_constant_disparity_exact(self, cost, min_disparity, shift):
        left, right = _shift_pair(shape=(60, 120), shift=shift, seed=5)
        lo = max(0, min_disparity + 31) + 8
        sl = np.s_[8:-8, lo:-8 - max(0, -min_disparity)]
        whole = compute_disparity(left, right, min_disparity=min_disparity, num_disparities=32, cost=cost,
                                  subpixel=False).disparity[sl]
        assert np.isfinite(whole).mean() > 0.98
        assert np.nanmax(np.abs(whole - shift)) == 0  # integer disparity recovered exactly
        sub = compute_disparity(left, right, min_disparity=min_disparity, num_disparities=32, cost=cost).disparity[sl]
        # white-noise texture: the parabola through uncorrelated neighbours moves by < 0.5 px, never to another integer
        assert np.nanmax(np.abs(sub - shift)) < 0.5 and np.nanmedian(np.abs(sub - shift)) < 0.1

    @pytest.mark.parametrize("cost, bound", [("census", 0.1), ("sad", 0.1)])
    def test_slanted_plane_subpixel(self, cost, bound):
        # measured mean |error|: census 0.086, sad 0.093 px (texture blurred with sigma 2; with sigma 1.2
        # both are about 0.11: the parabola locks towards integers on sharper textures)
        h, w = 80, 160
        left = _texture((h, w), seed=2, smooth=2.0)
        xs = np.arange(w, dtype=np.float32)[None, :].repeat(h, 0)
        ys = np.arange(h, dtype=np.float32)[:, None].repeat(w, 1)
        truth = (8.0 + 0.04 * xs + 0.03 * ys).astype(np.float32)  # 8 .. 16.7 px
        right = _warp_right(left, truth)
        pair = np.rint(left).astype(np.uint8), np.rint(right).astype(np.uint8)
        dmap = compute_disparity(*pair, num_disparities=24, subpixel=True, cost=cost, paths=8, lr_check=None,
                                 fill_holes=False)
        sl = np.s_[10:-10, 30:-10]
        err = np.abs(dmap.disparity[sl] - truth[sl])
        assert np.isfinite(err).mean() > 0.95
        assert np.nanmean(err) < bound
        whole = compute_disparity(*pair, num_disparities=24, subpixel=False, cost=cost, paths=8, lr_check=None,
                                  fill_holes=False)
        whole_err = np.abs(whole.disparity[sl] - truth[sl])
        assert np.nanmean(whole_err) == pytest.approx(0.25, abs=0.02)  # integer disparities: uniform rounding error
        assert np.nanmax(whole_err) < 1.0  # the smoothness term may delay a step by a pixel, never more

    def test_step(self):
        h, w = 60, 140
        left = _texture((h, w), seed=4, smooth=0.8)
        truth = np.where(np.arange(w)[None, :] < 70, 6.0, 14.0).astype(np.float32).repeat(h, 0)
        right = _warp_right(left, truth)
        dmap = compute_disparity(np.rint(left).astype(np.uint8), np.rint(right).astype(np.uint8), num_disparities=16)
        for cols, value in ((np.s_[24:60], 6.0), (np.s_[84:-8], 14.0)):
            part = dmap.disparity[8:-8, cols]
            assert np.isfinite(part).mean() > 0.95
            assert np.nanmedian(np.abs(part - value)) < 0.1
            assert np.mean(np.abs(part - value) < 1.0) > 0.95


# --------------------------------------------------------------------------------------------------
# error paths
# --------------------------------------------------------------------------------------------------
class TestErrors:
    @pytest.fixture
    def pair(self):
        return _shift_pair()

    def test_size_mismatch_names_both_shapes(self, pair):
        left, right = pair
        with pytest.raises(StereoInputError, match=re.escape("left (48, 96) and right (48, 90)")):
            compute_disparity(left, right[:, :90], num_disparities=16)

    def test_dtype_mismatch(self, pair):
        left, right = pair
        with pytest.raises(StereoInputError, match="same dtype"):
            compute_disparity(left, right.astype(np.uint16), num_disparities=16)

    @pytest.mark.parametrize("bad, pattern", [
        (np.zeros((0, 10), np.uint8), "must not be empty"),
        (np.zeros((10, 0, 3), np.uint8), "must not be empty"),
        (np.zeros((48, 96, 4), np.uint8), r"\(H, W, 3\), got shape \(48, 96, 4\)"),
        (np.zeros((2, 48, 96, 3), np.uint8), "got shape"),
        (np.zeros(96, np.uint8), "got shape"),
        (np.zeros((48, 96), np.int32), "dtype uint8, uint16, float32 or float64, got int32"),
        (np.zeros((48, 96), bool), "got bool"),
        (np.zeros((48, 96), np.float16), "got float16"),
        ("left.png", "read files with"),
        (None, "image array"),
        ([["a"]], "got <U1"),
    ])
    def test_bad_left_image(self, pair, bad, pattern):
        with pytest.raises(StereoInputError, match=pattern):
            compute_disparity(bad, pair[1], num_disparities=16)

    @pytest.mark.parametrize("which", ["left", "right"])
    @pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
    @pytest.mark.parametrize("dtype", [np.float32, np.float64])
    def test_non_finite(self, pair, which, value, dtype):
        left, right = (im.astype(dtype) for im in pair)
        (left if which == "left" else right)[3, 4] = value
        with pytest.raises(StereoInputError, match=f"`{which}` must hold finite values"):
            compute_disparity(left, right, num_disparities=16)

    @pytest.mark.parametrize("shape, kwargs", [
        ((4, 40), dict(num_disparities=8, cost="sad", block_size=5)),
        ((6, 40), dict(num_disparities=8, census_window=(9, 7))),
        ((20, 8), dict(num_disparities=4, census_window=(9, 7))),
    ])
    def test_too_small(self, shape, kwargs):
        img = np.zeros(shape, np.uint8)
        with pytest.raises(StereoInputError, match="images must be at least"):
            compute_disparity(img, img, **kwargs)

    def test_range_wider_than_image(self, pair):
        left, right = pair
        with pytest.raises(StereoInputError,
                           match=r"`num_disparities` \(128\) must not be larger than the image width \(96\)"):
            compute_disparity(left, right, num_disparities=128)
        with pytest.raises(StereoInputError, match=r"disparity range .*\(40\.\.103\)"):
            compute_disparity(left, right, min_disparity=40, num_disparities=64)
        with pytest.raises(StereoInputError, match="disparity range"):
            compute_disparity(left, right, min_disparity=-96, num_disparities=16)

    @pytest.mark.parametrize("kwargs, field", [(dict(num_disparities=0), "num_disparities"),
                                               (dict(block_size=4), "block_size"),
                                               (dict(num_disparities=-16), "num_disparities")])
    def test_bad_params_through_overrides(self, pair, kwargs, field):
        with pytest.raises(ValueError, match=f"`{field}`"):
            compute_disparity(*pair, **kwargs)

    def test_penalty_limit_is_checked_once_when_the_params_are_built(self, pair, monkeypatch):
        import sys

        params = SGMParams(num_disparities=16)  # frozen and checked here, P1/P2 limit included
        callers = []
        real = kernels.check_penalties

        def spy(*args):
            callers.append(sys._getframe(1).f_globals["__name__"])
            return real(*args)

        monkeypatch.setattr(kernels, "check_penalties", spy)
        compute_disparity(*pair, params)
        StereoMatcher(params).compute(*pair)
        # the kernels' entry point checks its own arguments; the matcher does not repeat the params' check
        assert "stereo_classic.matching.matcher" not in callers and "stereo_classic.matching.params" not in callers
        compute_disparity(*pair, params, p2=100)  # a changed field builds (and checks) new params
        assert callers.count("stereo_classic.matching.params") == 1

    @pytest.mark.parametrize("kwargs",
                             [dict(p1=10, p2=30000), dict(p1=10, p2=1400), dict(census_window=(3, 3), p2=1500)])
    def test_penalty_beyond_int16_sums(self, pair, kwargs):
        with pytest.raises(ValueError, match="`p2` too large"):
            SGMParams(**kwargs)
        with pytest.raises(ValueError, match="`p2` too large"):
            compute_disparity(*pair, num_disparities=16, **kwargs)

    def test_params_wrong_type(self, pair):
        with pytest.raises(ValueError, match="`params` must be an SGMParams"):
            compute_disparity(*pair, {"num_disparities": 16})
        with pytest.raises(ValueError, match="unknown SGM parameter"):
            StereoMatcher(ndisp=16)

    def test_memory_budget_refused_before_allocating(self, pair, monkeypatch):
        def boom(*args, **kwargs):
            raise AssertionError("allocated before the memory check")

        monkeypatch.setattr(matcher_mod, "_to_gray_uint8", boom)
        need = estimate_memory(pair[0].shape, SGMParams(num_disparities=16))
        with pytest.raises(MemoryBudgetError, match=r"needs about 0\.00 GiB .*num_disparities.*downscale"):
            compute_disparity(*pair, num_disparities=16, memory_limit=need - 1)
        monkeypatch.setenv(MEMORY_LIMIT_ENV, str(need - 1))
        with pytest.raises(MemoryBudgetError):
            compute_disparity(*pair, num_disparities=16)
        assert issubclass(MemoryBudgetError, ValueError) and issubclass(StereoInputError, ValueError)

    def test_memory_budget_large_image_message(self):
        # A 8K x 4K pair with 1024 disparities: refused from the shape alone, nothing allocated.
        big = np.lib.stride_tricks.as_strided(np.zeros(1, np.uint8), shape=(4320, 7680), strides=(0, 0))
        with pytest.raises(MemoryBudgetError,
                           match=r"7680 x 4320 px with num_disparities=1024 needs about \d+\.\d\d GiB"):
            compute_disparity(big, big, num_disparities=1024, memory_limit=2 * 1024**3)


# --------------------------------------------------------------------------------------------------
# load_kernels
# --------------------------------------------------------------------------------------------------
class TestLoadKernels:
    def test_matches_once_per_setting(self, monkeypatch):
        calls = []
        real = matcher_mod._match
        monkeypatch.setattr(matcher_mod, "_LOADED", set())
        monkeypatch.setattr(matcher_mod, "_match", lambda left, right, params, *a, **k: (
            calls.append((left.shape, left.flags.c_contiguous, right.flags.c_contiguous, params)),
            real(left, right, params, *a, **k))[1])
        assert matcher_mod.load_kernels(num_disparities=32, paths=4) is True
        # the same kernels: the range padded to the same disparities per pixel (32)
        assert matcher_mod.load_kernels(SGMParams(num_disparities=20, min_disparity=-7, paths=4)) is False
        assert matcher_mod.load_kernels(SGMParams(num_disparities=96, paths=4)) is True  # compiled per padded range
        assert matcher_mod.load_kernels(num_disparities=32, paths=8) is True
        assert matcher_mod.load_kernels(num_disparities=32, cost="sad", min_disparity=-40) is True
        # a range across zero wider than either end (the frame checks' look): the pair is wide enough for it
        assert matcher_mod.load_kernels(num_disparities=192, min_disparity=-64) is True
        # the pair the matcher's callers hand the kernels: C-contiguous uint8, wide enough for the range
        assert [(c[0], c[1], c[2], c[3].paths, c[3].cost) for c in calls] == [
            ((64, 96), True, True, 4, "census+grad"), ((64, 160), True, True, 4, "census+grad"),
            ((64, 96), True, True, 8, "census+grad"), ((64, 104), True, True, 3, "sad"),
            ((64, 256), True, True, 3, "census+grad")]

    def test_bad_parameters_named(self, monkeypatch):
        monkeypatch.setattr(matcher_mod, "_LOADED", set())
        with pytest.raises(ValueError, match="num_disparities"):
            matcher_mod.load_kernels(num_disparities=-16)
        with pytest.raises(ValueError, match="`params`"):
            matcher_mod.load_kernels({"num_disparities": 16})
        assert matcher_mod._LOADED == set()


# --------------------------------------------------------------------------------------------------
# estimate_memory, DisparityMap
# --------------------------------------------------------------------------------------------------
class TestEstimateMemory:
    def test_scales_with_range_and_options(self):
        base = estimate_memory((375, 1242), SGMParams(num_disparities=64))
        double = estimate_memory((375, 1242), SGMParams(num_disparities=128))
        eight = estimate_memory((375, 1242), SGMParams(num_disparities=64, paths=8))
        assert base < double and base < 375 * 1242 * 64 * 2 <= eight  # 3 paths: no sum volume; 8 paths keep one
        assert estimate_memory((375, 1242, 3), SGMParams(num_disparities=64)) == base
        assert estimate_memory((375, 1242), SGMParams(num_disparities=64, fill_holes=False)) < base
        assert estimate_memory((375, 1242), SGMParams(num_disparities=64, median_filter=True)) > base
        assert estimate_memory((375, 1242), SGMParams(num_disparities=64), dtype=np.float32) > base
        assert estimate_memory((375, 1242)) == base  # default params: 64 disparities

    @pytest.mark.parametrize("shape", [(10,), "10x10", (10, -1), (1.5, 2)])
    def test_bad_shape(self, shape):
        with pytest.raises(ValueError, match="`image_shape`"):
            estimate_memory(shape, SGMParams())

    def test_bad_params(self):
        with pytest.raises(ValueError, match="`params`"):
            estimate_memory((10, 10), {"num_disparities": 16})


class TestDisparityMap:
    def _ok(self, **kw):
        d = np.zeros((4, 5), np.float32)
        d[0, 0] = np.nan
        args = dict(disparity=d, disparity_right=None, params=SGMParams(), timings_ms={"total": 1.0},
                    validity={"valid": 19, "pixels": 20})
        args.update(kw)
        return DisparityMap(**args)

    def test_valid(self):
        m = self._ok()
        assert m.valid_fraction == pytest.approx(0.95) and m.shape == (4, 5)
        assert m.valid_mask.sum() == 19
        with pytest.raises(dataclasses.FrozenInstanceError):
            m.params = SGMParams()  # type: ignore[misc]

    @pytest.mark.parametrize("kw, pattern", [
        (dict(disparity=np.zeros((4, 5), np.float64)), "`disparity` must be a \\(H, W\\) float32"),
        (dict(disparity=np.zeros((4, 5, 1), np.float32)), "`disparity` must be"),
        (dict(disparity=np.full((4, 5), np.inf, np.float32)), "got inf"),
        (dict(disparity_right=np.zeros((4, 6), np.float32)), "`disparity_right`"),
        (dict(params={"num_disparities": 16}), "`params`"),
        (dict(timings_ms={"total": -1.0}), "`timings_ms`"),
        (dict(timings_ms={"total": float("nan")}), "`timings_ms`"),
        (dict(validity={"valid": -1}), "`validity`"),
        (dict(validity={"valid": 20}), "does not describe"),
    ])
    def test_invalid(self, kw, pattern):
        with pytest.raises(ValueError, match=pattern):
            self._ok(**kw)


# --------------------------------------------------------------------------------------------------
# property tests: a well-formed map or a documented error naming the parameter
# --------------------------------------------------------------------------------------------------
_DTYPES = st.sampled_from([np.uint8, np.uint16, np.float32, np.float64, np.int16, np.bool_])


@st.composite
def _pairs(draw):
    """A pair and params: about half well-formed (to exercise the matcher), half with one kind of defect."""
    hostile = draw(st.booleans())
    h = draw(st.integers(0, 24) if hostile else st.integers(7, 30))
    w = draw(st.integers(0, 48) if hostile else st.integers(9, 60))
    channels = draw(st.sampled_from([None, 1, 3, 4] if hostile else [None, 1, 3]))
    dtype = draw(_DTYPES if hostile else st.sampled_from([np.uint8, np.uint16, np.float32, np.float64]))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    shape = (h, w) if channels is None else (h, w, channels)
    scale = draw(st.sampled_from([1.0, 255.0, 65535.0, 1e30]))
    if np.dtype(dtype).kind in "iu":
        scale = min(scale, float(np.iinfo(dtype).max))
    left = (rng.uniform(0, 1, shape) * scale).astype(dtype)
    if draw(st.booleans()) and left.size:  # flat regions: ambiguous matches
        left[: h // 2] = left.flat[0]
    right = np.roll(left, draw(st.integers(0, 6)), axis=1) if w else left.copy()
    if hostile and draw(st.booleans()) and right.size and dtype in (np.float32, np.float64):
        right.flat[draw(st.integers(0, right.size - 1))] = draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    if hostile and draw(st.integers(0, 4)) == 0:
        right = right[:, : max(0, w - 1)]
    params = dict(
        min_disparity=draw(st.integers(-8, 8) if hostile else st.integers(-4, 4)),
        num_disparities=draw(st.integers(-2, 40) if hostile else st.integers(1, 20)),
        block_size=draw(st.integers(0, 8) if hostile else st.sampled_from([1, 3, 5, 7])),
        cost=draw(st.sampled_from(["census", "sad"])),
        census_window=draw(st.sampled_from([(9, 7), (5, 5), (3, 3), (7, 9), (1, 1)])),
        uniqueness=draw(st.sampled_from([0, 5.0, 50])),
        lr_check=draw(st.sampled_from([None, 0, 1.0, 3.0])),
        lr_mode=draw(st.sampled_from(["full", "opencv"])),
        right_view=draw(st.booleans()),
        subpixel=draw(st.booleans()),
        speckle_size=draw(st.sampled_from([0, 4, 100])),
        fill_holes=draw(st.booleans()),
        paths=draw(st.sampled_from([4, 8])),
        threads=draw(st.sampled_from([None, 1, 2])),
    )
    return left, right, params


@settings(max_examples=450, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(case=_pairs())
def test_property_well_formed_or_named_error(case):
    left, right, params = case
    try:
        dmap = compute_disparity(left, right, **params)
    except ValueError as exc:
        msg = str(exc)
        assert re.search(r"`[a-z_]+`|images must be at least", msg), msg
        return
    assert dmap.disparity.shape == left.shape[:2] and dmap.disparity.dtype == np.float32
    finite = dmap.disparity[np.isfinite(dmap.disparity)]
    assert not np.isinf(dmap.disparity).any()
    p = dmap.params
    assert ((finite >= p.min_disparity - 1) & (finite <= p.max_disparity + 1)).all()
    assert dmap.validity["valid"] == np.count_nonzero(np.isfinite(dmap.filled_disparity))
    assert finite.size == dmap.validity["valid"] - (0 if dmap.filled is None else np.count_nonzero(dmap.filled))


@pytest.mark.parametrize("threads", [1, 2, 3])
@pytest.mark.parametrize("paths", [3, 8])
def test_speckle_labels_made_while_matching_change_nothing(monkeypatch, threads, paths):
    """The matcher labels the speckle filter's regions stripe by stripe as the kernels finish them (and counts the
    unknown and short-reach pixels there): the same result, every count included, as the labelling of the finished
    map, for any thread count; ``sgm_match`` calls it once for every stripe."""
    monkeypatch.setattr(kernels, "usable_cpus", lambda: 8)
    tex = _texture((230, 150), seed=3)
    d_true = np.fromfunction(lambda y, x: 6 + 5 * (x > 75) + y / 60.0, tex.shape).astype(np.float32)
    left = np.round(tex).astype(np.uint8)
    right = np.round(_warp_right(tex, d_true)).astype(np.uint8)
    right[100:140, 20:60] = 255  # a blank patch: unknown pixels and small regions for the filter
    params = SGMParams(num_disparities=32, threads=threads, paths=paths, speckle_size=60)
    assert len(kernels.stripes(left.shape[0])) >= 4
    calls = []  # the stripes labelled while matching: the matcher's ``on_rows``
    sgm_match = kernels.sgm_match

    def counting(*args, on_rows=None, **kw):
        seen = None if on_rows is None else lambda d, y0, y1: (calls.append((y0, y1)), on_rows(d, y0, y1))
        return sgm_match(*args, on_rows=seen, **kw)

    monkeypatch.setattr(kernels, "sgm_match", counting)
    fused = compute_disparity(left, right, params)
    assert sorted(calls) == kernels.stripes(left.shape[0])
    monkeypatch.setattr(matcher_mod.StripeLabels, "fits", staticmethod(lambda bound: False))
    after = compute_disparity(left, right, params)
    assert len(calls) == len(kernels.stripes(left.shape[0]))  # the second call did not label while matching
    for name in ("disparity", "filled_disparity", "filled", "disparity_right"):
        np.testing.assert_array_equal(getattr(fused, name), getattr(after, name))
    assert fused.validity == after.validity
    assert fused.validity["short_range"] > 0 and fused.validity["unknown_matcher"] > 0
    assert fused.validity["speckle_removed"] > 0 and fused.validity["filled"] > 0
