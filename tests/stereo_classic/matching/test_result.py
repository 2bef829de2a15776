"""stereo_classic.matching.result.DisparityMap: measured by default, filled by name (issue 31)."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_classic.matching import SGMParams
from stereo_classic.matching.result import DisparityMap


def test_constructor_moves_the_fills_to_filled_disparity():
    d = np.arange(12, dtype=np.float32).reshape(3, 4)
    d[0, 0] = np.nan
    filled = np.zeros((3, 4), bool)
    filled[1, 1:3] = True
    m = DisparityMap(d, None, SGMParams(), validity={"valid": 11}, filled=filled)
    assert m.filled_disparity is d and np.isnan(m.disparity[filled]).all() and np.isnan(m.disparity[0, 0])
    assert np.array_equal(m.disparity[~filled], d[~filled], equal_nan=True)
    assert m.measured_disparity is m.disparity and m.valid_mask.sum() == 9
    assert m.valid_fraction == m.measured_fraction == pytest.approx(9 / 12) and m.validity["valid"] == 11
    plain = DisparityMap(d, None, SGMParams())
    assert plain.disparity is d and plain.filled_disparity is d  # nothing filled: one array


def test_confidence_is_zero_off_the_measured_pixels_and_computed_once():
    d = np.full((20, 30), 4.0, np.float32)
    d[:, :5] = np.nan
    gray = np.tile((np.arange(30) * 8 % 256).astype(np.uint8), (20, 1))
    m = DisparityMap(d, None, SGMParams(), left_gray=gray)
    c = m.confidence
    assert c.dtype == np.uint8 and (c[:, :5] == 0).all() and (c[:, 5:] > 0).all() and m.confidence is c
    assert not c.flags.writeable


@pytest.mark.parametrize("name, value", [("left_gray", np.zeros((3, 4), np.float32)),
                                         ("filled", np.zeros((2, 4), bool)),
                                         ("disparity_right", np.zeros((3, 4), np.float64))])
def test_bad_arrays_are_named(name, value):
    args = {"disparity": np.zeros((3, 4), np.float32), "disparity_right": None, "params": SGMParams(), name: value}
    with pytest.raises(ValueError, match=f"`{name}`"):
        DisparityMap(**args)


@pytest.mark.parametrize("order", ["C", "F"])
def test_one_pass_and_numpy_checks_agree(order):
    """C-contiguous maps (the matcher's) are checked and split in one numba pass, others by NumPy: the same
    measured map bit for bit, the same counts and the same errors."""
    rng = np.random.default_rng(3)
    d = rng.uniform(0, 60, (17, 23)).astype(np.float32)
    d[rng.random(d.shape) < 0.2] = np.nan
    filled = (rng.random(d.shape) < 0.3) & np.isfinite(d)
    d, filled = np.asarray(d, order=order), np.asarray(filled, order=order)
    m = DisparityMap(d, None, SGMParams(), filled=filled)
    want = np.where(filled, np.float32(np.nan), d)
    assert m.disparity.tobytes() == np.ascontiguousarray(want).tobytes() and m.filled_disparity is d
    assert m.validity["valid"] == int(np.isfinite(d).sum())
    for bad, match in ((np.inf, "inf"), (np.nan, "`filled` marks")):
        e = d.copy(order=order)
        e[np.argwhere(filled)[0][0], np.argwhere(filled)[0][1]] = bad
        with pytest.raises(ValueError, match=match):
            DisparityMap(e, None, SGMParams(), filled=filled)
    with pytest.raises(ValueError, match="does not describe"):
        DisparityMap(d, None, SGMParams(), filled=filled, validity={"valid": 1})


def test_the_matchers_one_pass_maps_make_the_same_object():
    """``DisparityMap._of_one_pass`` (the post-processing's measured map and counts instead of the constructor's pass)
    makes what the constructor makes of the filled map, and still checks what the pass does not vouch for."""
    from stereo_classic.matching.postprocess import _speckle_fill_counted

    rng = np.random.default_rng(3)
    d = np.round(rng.uniform(0, 40, (90, 70)) * 0.25).astype(np.float32)
    d[rng.random(d.shape) < 0.4] = np.nan
    d[10] = np.nan
    out, holes, kept, filled, measured = _speckle_fill_counted(d, max_size=5, max_diff=1.0, threads=2)
    assert measured is not None and filled > 0
    validity = {"valid": kept + filled, "pixels": d.size}
    a = DisparityMap._of_one_pass(out, holes, measured, kept, filled, disparity_right=None, params=SGMParams(),
                                  validity=validity)
    b = DisparityMap(disparity=out, disparity_right=None, params=SGMParams(), validity=validity, filled=holes)
    for name in ("disparity", "filled_disparity", "filled"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert a.validity == b.validity and a.disparity is measured
    with pytest.raises(ValueError, match="does not describe"):
        DisparityMap._of_one_pass(out, holes, measured, kept, filled, disparity_right=None, params=SGMParams(),
                                  validity={"valid": kept})
    c = DisparityMap(disparity=out, disparity_right=None, params=SGMParams(), filled=holes)  # the hand-over is gone
    assert c.disparity is not measured
