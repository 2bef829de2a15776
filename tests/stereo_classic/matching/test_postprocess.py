"""Post-processing (stereo_classic.matching.postprocess): speckle filter and hole filling."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stereo_classic.matching._kernels import core as _kernels
from stereo_classic.matching.postprocess import StripeLabels, fill_holes, fill_holes_marked, filter_speckles


# --------------------------------------------------------------------------------------------------
# post-processing
# --------------------------------------------------------------------------------------------------
class TestPostprocess:
    def test_speckles_removed_large_regions_kept(self):
        d = np.full((30, 30), 10.0, np.float32)
        d[5:7, 5:7] = 20.0  # 4-pixel speckle
        d[15:25, 15:25] = 30.0  # 100-pixel region
        d[0, :] = np.nan
        out = filter_speckles(d, max_size=10, max_diff=1.0)
        assert np.isnan(out[5:7, 5:7]).all() and np.isfinite(out[15:25, 15:25]).all()
        assert np.isnan(out).sum() == 4 + 30
        assert np.isnan(d).sum() == 30  # input untouched
        # a range wider than the jump merges the speckle with its surroundings
        d2 = d.copy()
        d2[5:7, 5:7] = 10.5
        assert np.isnan(filter_speckles(d2, max_size=10, max_diff=1.0)).sum() == 30
        np.testing.assert_array_equal(filter_speckles(d, max_size=0, max_diff=1.0), d)

    def test_speckles_subpixel_range_and_large_disparity(self):
        d = np.full((20, 20), 3000.0, np.float32)  # d * 16 would overflow int16: scaled down instead
        d[3, 3] = 3010.0
        out = filter_speckles(d, max_size=5, max_diff=2.0)
        assert np.isnan(out).sum() == 1 and np.isnan(out[3, 3])
        ramp = np.tile(np.arange(20, dtype=np.float32) * 0.25, (20, 1))  # steps of 0.25 px: one region
        assert not np.isnan(filter_speckles(ramp, max_size=50, max_diff=0.3)).any()
        assert np.isnan(filter_speckles(ramp, max_size=50, max_diff=0.2)).all()

    def test_fill_holes_background(self):
        d = np.array([[5, np.nan, np.nan, 9, np.nan], [np.nan] * 5, [1, 2, 3, 4, 5]], np.float32)
        out = fill_holes(d)
        assert np.isnan(out[1]).all()  # nothing known in the row
        np.testing.assert_array_equal(out[2], d[2])
        assert np.isfinite(out[0]).all() and out[0, 0] == 5 and out[0, 3] == 9
        assert np.isnan(d[0, 1])  # input untouched
        wide = np.full((9, 20), 20.0, np.float32)
        wide[:, 12:] = 4.0
        wide[:, 8:12] = np.nan  # hole between a near (20) and a far (4) surface: background is 4
        np.testing.assert_array_equal(fill_holes(wide)[2:-2, 8:12], 4.0)
        # a row between two empty rows: the median never sees the empty rows' placeholder
        lone = np.full((5, 6), np.nan, np.float32)
        lone[2, 0] = 7.0
        np.testing.assert_array_equal(fill_holes(lone)[2], 7.0)

    @pytest.mark.parametrize("func", [lambda d: filter_speckles(d, max_size=1, max_diff=1), fill_holes])
    def test_rejects_wrong_dtype(self, func):
        with pytest.raises(ValueError, match="`disparity` must be a \\(H, W\\) float32"):
            func(np.zeros((3, 3)))


@st.composite
def _disparity_maps(draw):
    h, w = draw(st.integers(1, 30)), draw(st.integers(1, 30))
    rng = np.random.default_rng(draw(st.integers(0, 2**16)))
    scale = draw(st.sampled_from([1.0, 64.0, 5000.0]))
    d = (rng.normal(0, 1, (h, w)).cumsum(axis=1) * scale / 10).astype(np.float32)
    d[rng.random((h, w)) < draw(st.sampled_from([0.0, 0.2, 0.9, 1.0]))] = np.nan
    return d


@settings(max_examples=240, deadline=None)
@given(d=_disparity_maps(), max_size=st.integers(0, 50), max_diff=st.sampled_from([0.0, 0.5, 2.0, 100.0]))
def test_property_postprocess(d, max_size, max_diff):
    known = np.isfinite(d)
    out = filter_speckles(d, max_size=max_size, max_diff=max_diff)
    kept = np.isfinite(out)
    assert out.dtype == np.float32 and not (kept & ~known).any()  # only removes
    np.testing.assert_array_equal(out[kept], d[kept])  # never changes a value
    if max_size == 0:
        assert (kept == known).all()
    filled = fill_holes(d)
    np.testing.assert_array_equal(filled[known], d[known])
    rows_with_data = known.any(axis=1)
    assert np.isfinite(filled[rows_with_data]).all() and np.isnan(filled[~rows_with_data]).all()
    lo, hi = (np.nanmin(d), np.nanmax(d)) if known.any() else (0, 0)
    assert ((filled[np.isfinite(filled)] >= lo) & (filled[np.isfinite(filled)] <= hi)).all()


def _fill_reference(disp):
    """The row background fill written with numpy (the definition the numba kernel must match)."""
    valid = np.isfinite(disp)
    if valid.all() or not valid.any():
        return disp.copy()
    height, width = disp.shape
    columns = np.broadcast_to(np.arange(width), disp.shape)
    left_idx = np.maximum.accumulate(np.where(valid, columns, -1), axis=1)
    right_idx = np.minimum.accumulate(np.where(valid, columns, width)[:, ::-1], axis=1)[:, ::-1]
    safe = np.where(valid, disp, np.inf)
    left_val = np.take_along_axis(safe, np.clip(left_idx, 0, width - 1), axis=1)
    right_val = np.take_along_axis(safe, np.clip(right_idx, 0, width - 1), axis=1)
    left_val[left_idx < 0] = np.inf
    right_val[right_idx >= width] = np.inf
    filled = np.where(valid, disp, np.minimum(left_val, right_val)).astype(np.float32)
    still_unknown = ~np.isfinite(filled)
    filled[still_unknown] = 0.0
    median = cv2.medianBlur(filled, 3)
    holes = ~valid & ~still_unknown
    out = disp.copy()
    out[holes] = filled[holes]
    if still_unknown.any():
        near_empty = cv2.dilate(still_unknown.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        holes &= ~near_empty
    out[holes] = median[holes]
    out[still_unknown] = np.nan
    return out


def test_fill_holes_equals_the_numpy_definition_on_random_maps():
    rng = np.random.default_rng(7)
    for _ in range(150):
        h, w = int(rng.integers(1, 25)), int(rng.integers(1, 35))
        d = rng.uniform(0, 60, (h, w)).astype(np.float32)
        d[rng.random((h, w)) < rng.uniform(0, 1)] = np.nan
        if rng.random() < 0.3:
            d[int(rng.integers(0, h))] = np.nan  # a row without any known pixel
        np.testing.assert_array_equal(fill_holes(d), _fill_reference(d))
        out, mask = fill_holes_marked(d)
        np.testing.assert_array_equal(out, _fill_reference(d))
        np.testing.assert_array_equal(mask, ~np.isfinite(d) & np.isfinite(out))


def _speckle_reference(disp, max_size, max_diff):
    """The speckle filter written with numpy: scale to 1/16 px int16 (less for large magnitudes), OpenCV's filter."""
    out = disp.copy()
    valid = np.isfinite(disp)
    if max_size == 0 or not valid.any():
        return out
    magnitude = float(np.abs(disp[valid]).max())
    scale = 16.0 if magnitude * 16.0 <= 32000.0 else 32000.0 / magnitude
    work = np.where(valid, np.rint(np.where(valid, disp, 0) * np.float32(scale)), -32768).astype(np.int16)
    cv2.filterSpeckles(work, -32768, int(max_size), int(round(max_diff * scale)))
    out[work == -32768] = np.nan
    return out


def test_filter_speckles_equals_the_numpy_definition_on_random_maps():
    rng = np.random.default_rng(8)
    for i in range(120):
        h, w = int(rng.integers(1, 30)), int(rng.integers(1, 40))
        d = np.round(rng.uniform(-5, 60, (h, w)) * 4).astype(np.float32) / 4  # plateaus and speckles
        d[rng.random((h, w)) < rng.uniform(0, 0.5)] = np.nan
        if i % 10 == 0:
            d[0, 0] = np.inf  # not finite: unknown
        if i % 17 == 0:
            d *= np.float32(700.0)  # magnitudes beyond 2000 px: a coarser scale
        size, diff = int(rng.integers(0, 12)), float(rng.choice([0.0, 0.5, 2.0]))
        np.testing.assert_array_equal(filter_speckles(d, max_size=size, max_diff=diff), _speckle_reference(d, size, diff))


@pytest.mark.parametrize("threads", [1, 2, 3, 5])
def test_speckles_and_fill_in_stripes_equal_opencv_for_any_thread_count(threads):
    """Maps tall enough for several stripes (regions cross the stripes' borders): the filter equals OpenCV's and
    the fill the numpy definition, for every thread count."""
    rng = np.random.default_rng(9)
    for i in range(12):
        h, w = int(rng.integers(60, 260)), int(rng.integers(1, 120))
        d = np.round(rng.uniform(-5, 60, (h, w)) * rng.choice([0.02, 0.25])).astype(np.float32)  # plateaus
        d[rng.random((h, w)) < rng.uniform(0, 0.5)] = np.nan
        if i % 4 == 0:
            d[:, int(rng.integers(0, w))] = 3.0  # a column-long region through every stripe
        for size in (0, 4, 60, 5000):
            np.testing.assert_array_equal(filter_speckles(d, max_size=size, max_diff=1.0, threads=threads),
                                          _speckle_reference(d, size, 1.0))
        np.testing.assert_array_equal(fill_holes(d, threads=threads), _fill_reference(d))


@pytest.mark.parametrize("threads", [1, 2, 3, 5])
def test_speckle_filter_and_fill_in_one_pass_equal_the_two_steps(threads):
    """What the matcher runs when both are on (``_speckle_fill_counted``: the filter's labels, then the filter, the
    row fill and the median in one pass) equals the fill of the filtered map, pixel for pixel, with the same
    counts: rows without any known pixel (alone, in pairs, at the image borders), maps of one row or column,
    regions across the stripes' borders, every thread count."""
    from stereo_classic.matching.postprocess import _speckle_fill_counted

    rng = np.random.default_rng(10)
    for i in range(60):
        h = int(rng.integers(1, 8)) if i % 5 == 0 else int(rng.integers(40, 220))
        w = int(rng.integers(1, 4)) if i % 7 == 0 else int(rng.integers(1, 90))
        d = np.round(rng.uniform(-5, 60, (h, w)) * rng.choice([0.02, 0.25, 4.0])).astype(np.float32)
        d[rng.random((h, w)) < rng.uniform(0, 0.9)] = np.nan
        if i % 3 == 0:
            rows = rng.integers(0, h, int(rng.integers(1, 4)))
            d[rows] = np.nan
            d[np.clip(rows + 1, 0, h - 1)] = np.nan
        if i % 4 == 0:
            d[[0, h - 1]] = np.nan
        if i % 11 == 0:
            d[0, 0] = np.inf
        for size in (0, 1, 4, 60):
            expected = filter_speckles(d, max_size=size, max_diff=1.0)
            out, holes, kept, filled, measured = _speckle_fill_counted(d, max_size=size, max_diff=1.0,
                                                                       threads=threads)
            np.testing.assert_array_equal(out, _fill_reference(expected))
            np.testing.assert_array_equal(holes, ~np.isfinite(expected) & np.isfinite(out))
            assert kept == int(np.isfinite(expected).sum()) and filled == int(holes.sum())
            if measured is not None:  # the filtered map: the filled one with NaN where filled
                np.testing.assert_array_equal(measured, np.where(holes, np.float32(np.nan), out))
                np.testing.assert_array_equal(measured, np.where(np.isfinite(expected), expected, np.float32(np.nan)))
            # the matcher's bound on the magnitudes instead of a scan for them: the same
            finite = np.abs(d[np.isfinite(d)])
            bound = float(finite.max()) + 1.0 if finite.size else 1.0
            again = _speckle_fill_counted(d, max_size=size, max_diff=1.0, threads=threads, bound=bound)
            np.testing.assert_array_equal(again[0], out)
            np.testing.assert_array_equal(again[1], holes)
            assert again[2:4] == (kept, filled)
            if size == 0:
                continue
            # the matcher's labels made stripe by stripe, in any order, as it finishes them (``StripeLabels``)
            labelled = StripeLabels(d.shape, 1.0, bound)
            for j in rng.permutation(len(_kernels.stripes(h))):
                labelled.label(d, *_kernels.stripes(h)[j])
            fused = _speckle_fill_counted(d, max_size=size, max_diff=1.0, threads=threads, bound=bound,
                                          labelled=labelled)
            np.testing.assert_array_equal(fused[0], out)
            np.testing.assert_array_equal(fused[1], holes)
            assert fused[2:4] == (kept, filled)
            np.testing.assert_array_equal(fused[4], again[4])


def test_stripe_labels_refuse_what_they_were_not_made_of():
    from stereo_classic.matching.postprocess import _speckle_and_fill, _speckle_fill_counted

    d = np.full((120, 30), 5.0, np.float32)
    bands = _kernels.stripes(120)
    assert len(bands) >= 2 and not StripeLabels.fits(5000.0) and StripeLabels.fits(6.0)
    with pytest.raises(ValueError, match="bound"):
        StripeLabels(d.shape, 1.0, 5000.0)
    labelled = StripeLabels(d.shape, 1.0, 6.0)
    for band in bands[1:]:
        labelled.label(d, *band)
    with pytest.raises(ValueError, match="not labelled"):  # the first stripe is missing
        _speckle_fill_counted(d, max_size=10, max_diff=1.0, bound=6.0, labelled=labelled)
    with pytest.raises(ValueError, match="one map"):
        labelled.label(d.copy(), *bands[0])
    labelled.label(d, *bands[0])
    with pytest.raises(ValueError, match="same `bound`"):
        _speckle_fill_counted(d, max_size=10, max_diff=1.0, bound=7.0, labelled=labelled)
    with pytest.raises(ValueError, match="same `bound`"):
        _speckle_fill_counted(d.copy(), max_size=10, max_diff=1.0, bound=6.0, labelled=labelled)
    with pytest.raises(ValueError, match="needs both"):
        _speckle_and_fill(d, max_size=10, max_diff=1.0, fill=False, bound=6.0, labelled=labelled)
    out = _speckle_fill_counted(d, max_size=10, max_diff=1.0, bound=6.0, labelled=labelled)
    np.testing.assert_array_equal(out[0], d)


def test_postprocess_stays_within_its_memory_estimate():
    import tracemalloc

    from stereo_classic.matching.postprocess import (
        _speckle_fill_counted,
        fill_bytes,
        median_bytes,
        median_measured,
        speckle_bytes,
        speckle_fill_bytes,
    )

    rng = np.random.default_rng(4)
    d = np.round(rng.uniform(0, 60, (300, 400)) * 0.25).astype(np.float32)
    d[rng.random(d.shape) < 0.3] = np.nan
    d[7] = np.nan  # a row without any known pixel: the fill's masked path
    filter_speckles(d[:50], max_size=10, max_diff=1.0)  # first-call allocations out of the way
    fill_holes(d[:50])
    _speckle_fill_counted(d[:50], max_size=10, max_diff=1.0)
    median_measured(d[:50])
    for func, budget in ((lambda: filter_speckles(d, max_size=10, max_diff=1.0), speckle_bytes(*d.shape)),
                         (lambda: fill_holes(d), fill_bytes(*d.shape)),
                         (lambda: _speckle_fill_counted(d, max_size=10, max_diff=1.0), speckle_fill_bytes(*d.shape)),
                         (lambda: median_measured(d), median_bytes(*d.shape))):
        tracemalloc.start()
        try:
            base = tracemalloc.get_traced_memory()[0]
            func()
            peak = tracemalloc.get_traced_memory()[1] - base
        finally:
            tracemalloc.stop()
        assert peak <= budget + 64 * 1024, (peak / d.size, budget / d.size)


@pytest.mark.parametrize("kwargs, match", [
    (dict(max_size=-1, max_diff=1.0), "`max_size` must be a non-negative integer"),
    (dict(max_size=2.5, max_diff=1.0), "`max_size` must be a non-negative integer"),
    (dict(max_size=3, max_diff=-1.0), "`max_diff` must be a non-negative number"),
    (dict(max_size=3, max_diff=1.0, threads=0), "`threads` must be a positive integer"),
])
def test_filter_speckles_names_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        filter_speckles(np.zeros((4, 4), np.float32), **kwargs)
    with pytest.raises(ValueError, match="`threads` must be a positive integer"):
        fill_holes(np.zeros((4, 4), np.float32), threads=1.5)


def test_filter_speckles_refuses_maps_beyond_its_int32_labels(monkeypatch):
    from stereo_classic.matching import postprocess

    monkeypatch.setattr(postprocess, "_MAX_LABELS", 16)
    with pytest.raises(ValueError, match="`disparity` has 16 pixels; the speckle filter labels at most 15"):
        filter_speckles(np.zeros((4, 4), np.float32), max_size=3, max_diff=1.0)
    filter_speckles(np.zeros((3, 5), np.float32), max_size=3, max_diff=1.0)  # 15 pixels: fine


def _median_reference(d, holes):
    """The 3x3 median of the measurements written with numpy: every measured pixel (finite, not a hole) the
    ((n - 1) // 2)-th smallest of the n measured values of its 3x3 neighbourhood; every other pixel as given."""
    h, w = d.shape
    measured = np.where(holes | ~np.isfinite(d), np.nan, d).astype(np.float32)
    padded = np.pad(measured, 1, constant_values=np.nan)
    stack = np.stack([padded[i:i + h, j:j + w] for i in range(3) for j in range(3)])
    n = np.isfinite(stack).sum(axis=0)
    k = np.maximum((n - 1) // 2, 0)
    lower = np.take_along_axis(np.sort(stack, axis=0), k[None], axis=0)[0]  # NaN sorts last
    return np.where(np.isfinite(measured), lower, d).astype(np.float32)


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_median_of_the_measurements_equals_the_numpy_definition(threads):
    from stereo_classic.matching.postprocess import median_measured

    rng = np.random.default_rng(11)
    for _ in range(60):
        h, w = int(rng.integers(1, 130)), int(rng.integers(1, 40))
        d = rng.uniform(-5, 60, (h, w)).astype(np.float32)
        d[rng.random((h, w)) < rng.uniform(0, 0.8)] = np.nan
        holes = ~np.isfinite(d) & (rng.random((h, w)) < 0.5)
        d[holes] = rng.uniform(0, 60, int(holes.sum())).astype(np.float32)  # the fill's values: never read
        np.testing.assert_array_equal(median_measured(d, holes, threads=threads), _median_reference(d, holes))
        plain = np.where(holes, np.nan, d).astype(np.float32)
        np.testing.assert_array_equal(median_measured(plain, threads=threads),
                                      _median_reference(plain, np.zeros((h, w), bool)))


def test_median_of_the_measurements_outvotes_one_pixel_and_keeps_a_step():
    from stereo_classic.matching.postprocess import median_measured

    d = np.full((9, 12), 20.0, np.float32)
    d[:, 6:] = 10.0  # a depth step: each side keeps its value up to the edge
    d[4, 2] = 35.0  # one wrong winner
    d[0, 0] = np.nan
    out = median_measured(d)
    assert out[4, 2] == 20.0 and np.isnan(out[0, 0])
    np.testing.assert_array_equal(out[:, 5], 20.0)  # lower median of 20,20,20,20,20,20,10,10,10 (or fewer)
    np.testing.assert_array_equal(out[:, 6], 10.0)
    assert out.dtype == np.float32 and out is not d


@pytest.mark.parametrize("kwargs, match", [
    (dict(threads=0), "`threads` must be a positive integer"),
    (dict(holes=np.zeros((3, 3), np.uint8)), "`holes` must be a \\(H, W\\) bool array"),
    (dict(holes=np.zeros((2, 3), bool)), "`holes` must be a \\(H, W\\) bool array"),
])
def test_median_of_the_measurements_names_bad_arguments(kwargs, match):
    from stereo_classic.matching.postprocess import median_measured

    with pytest.raises(ValueError, match=match):
        median_measured(np.zeros((3, 3), np.float32), **kwargs)
    with pytest.raises(ValueError, match="`disparity` must be a \\(H, W\\) float32 array"):
        median_measured(np.zeros((3, 3), np.float64))
