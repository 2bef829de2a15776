"""Post-processing (stereo_classic.matching.postprocess): speckle filter and hole filling."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stereo_classic.matching.postprocess import fill_holes, filter_speckles


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
