"""stereo_classic.matching.confidence and DisparityMap.confidence: textured against textureless halves."""

from __future__ import annotations

import numpy as np
import pytest

import stereo_classic as sc
from stereo_classic.matching.confidence import confidence_map, lr_agreement, texture_strength


def _halves(seed: int = 0, shift: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """A pair shifted by ``shift`` px: random texture on the left half, a flat grey with sensor-like noise
    (sigma 1 grey level) on the right half."""
    rng = np.random.default_rng(seed)
    h, w = 120, 200
    right = rng.integers(0, 256, (h, w)).astype(np.float32)
    right[:, w // 2:] = 128 + rng.normal(0.0, 1.0, (h, w - w // 2))
    right = np.clip(right, 0, 255).astype(np.uint8)
    return np.roll(right, shift, axis=1), right


def test_textured_half_is_confident_and_the_textureless_half_is_not():
    left, right = _halves()
    dmap = sc.compute_disparity(left, right, num_disparities=32)
    conf = dmap.confidence
    assert conf.dtype == np.uint8 and conf.shape == dmap.shape
    textured, flat = conf[:, 40:90], conf[:, 120:190]
    # the matcher measures the flat half too (propagated along its paths, right here), but nothing was matched there
    assert np.isfinite(dmap.disparity[:, 120:190]).mean() > 0.9
    assert (textured >= 128).mean() > 0.95 and (flat < 128).mean() > 0.95
    assert np.median(textured) > 3 * np.median(flat)


def test_zero_exactly_where_nothing_was_measured_filled_included():
    left, right = _halves(seed=1)
    left[30:60, 20:50] = 255  # a blank patch in one view only: unmatched pixels, filled from the background
    dmap = sc.compute_disparity(left, right, num_disparities=32)
    assert dmap.filled is not None and dmap.filled.any()
    conf = dmap.confidence
    measured = np.isfinite(dmap.disparity)
    assert (conf[~measured] == 0).all() and (conf[measured] >= 1).all() and (conf[dmap.filled] == 0).all()
    assert dmap.confidence is conf  # computed once


def test_left_right_disagreement_lowers_the_confidence():
    d = np.full((4, 20), 5.0, np.float32)
    right = np.full((4, 20), 5.0, np.float32)
    right[:, :8] = 4.0  # the right pixels x - 5 for x = 5..12 say 4: 1 px apart
    agree = lr_agreement(d, right, 1.0)
    assert np.allclose(agree[:, 14:], 1.0) and np.allclose(agree[:, 5:13], 0.5)
    assert (agree[:, :5] == 0).all()  # x - d outside the right image: the views cannot agree there
    assert (confidence_map(d, right, None)[:, 5:13] == 128).all()


def test_texture_strength_is_the_matchers_weak_texture_measure():
    flat = np.full((20, 30), 90, np.uint8)
    ramp = np.tile((np.arange(30) * 8).astype(np.uint8), (20, 1))  # |Sobel_x| = 8 * 2 * 4 = 64 > 16
    assert np.allclose(texture_strength(flat), 0.0) and np.allclose(texture_strength(ramp)[:, 3:-3], 1.0)


@pytest.mark.parametrize("bad", [np.zeros((3, 3), np.float32), np.zeros((3,), np.uint8)])
def test_bad_input_is_named(bad):
    with pytest.raises(ValueError, match="`left_gray`"):
        texture_strength(bad)
