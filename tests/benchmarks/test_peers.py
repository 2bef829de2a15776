"""benchmarks.peers: the ``pandora`` method (CNES Pandora + libSGM, the extra ``.[peers]``).

Without the extra the method is listed as not available and says how to install it; with it, it runs and its
output follows this project's convention (d = x_left - x_right, NaN unknown)."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from benchmarks.methods import Setup, default_methods, output_views, peer_methods
from benchmarks.peers import PANDORA_PIPELINE, pandora_available

HAVE_PEERS = all(importlib.util.find_spec(m) is not None for m in ("pandora", "pandora_plugin_libsgm"))


def test_pandora_is_listed_with_the_configuration_of_issue_35():
    (method,) = peer_methods()
    assert method.name == "pandora" and method.family == "peer"
    assert [m.name for m in default_methods(["pandora"])] == ["pandora"]
    assert "single-threaded" in method.description
    pipe = PANDORA_PIPELINE
    assert (pipe["matching_cost"]["matching_cost_method"], pipe["matching_cost"]["window_size"]) == ("census", 5)
    assert pipe["optimization"]["penalty"]["P1"] == 8 and pipe["optimization"]["penalty"]["P2"] == 32
    assert pipe["refinement"]["refinement_method"] == "vfit"
    assert pipe["validation"]["validation_method"] == "cross_checking_accurate"
    assert pipe["filter"]["filter_size"] == pipe["filter.after"]["filter_size"] == 3
    assert method.available == HAVE_PEERS == pandora_available()[0]


@pytest.mark.skipif(HAVE_PEERS, reason="the extra .[peers] is installed: the missing case cannot be seen here")
def test_without_the_extra_pandora_says_how_to_install_it():
    (method,) = peer_methods()
    assert not method.available and ".[peers]" in method.reason
    with pytest.raises(RuntimeError, match="not available"):
        method.prepare(Setup(num_disparities=16))


@pytest.mark.skipif(not HAVE_PEERS, reason="the extra .[peers] (pandora, pandora-plugin-libsgm) is not installed")
def test_pandora_disparity_is_x_left_minus_x_right_with_nan_unknown():
    rng = np.random.default_rng(3)
    right = rng.integers(0, 256, (40, 96), dtype=np.uint8)
    shift = 6
    left = np.roll(right, shift, axis=1)  # left(x) = right(x - 6): d = +6
    (method,) = peer_methods()
    disp, measured = output_views(method.prepare(Setup(num_disparities=16))(left, right), left.shape)
    assert disp is measured and disp.dtype == np.float32
    inner = disp[4:-4, 24:-4]
    assert np.isfinite(inner).mean() > 0.95
    assert np.nanmedian(inner) == pytest.approx(shift, abs=0.25)
    assert np.isnan(disp[:, :2]).all()  # left border: no match in the right image, invalid in Pandora's mask
    colour = np.repeat(left[..., None], 3, axis=2), np.repeat(right[..., None], 3, axis=2)
    np.testing.assert_array_equal(method.prepare(Setup(num_disparities=16))(*colour), disp)  # BGR in: grey
