"""benchmarks.methods: the matcher variants and output_views (output and measured pixels of a method)."""

from __future__ import annotations

import numpy as np
import pytest

import stereo_classic as sc
from benchmarks.methods import (
    Setup,
    default_methods,
    output_views,
    stereo_classic_methods,
)


def test_matcher_variants_and_their_settings():
    methods = {m.name: m for m in stereo_classic_methods()}
    assert list(methods) == ["sc-default", "sc-mccnn", "sc-mccnn-net", "sc-mccnn-int8", "sc-census-8", "sc-census-3",
                             "sc-8", "sc-independent", "sc-sad-8"]
    assert methods["sc-mccnn"].params["cost"] == "mccnn"
    assert (methods["sc-mccnn"].params["feature_census"], methods["sc-mccnn-net"].params["feature_census"]) == (None, 0.0)
    default = sc.SGMParams()
    assert methods["sc-default"].params["cost"] == default.cost and methods["sc-default"].params["paths"] == default.paths
    old = methods["sc-census-8"].params
    assert (old["cost"], old["paths"], old["lr_check"], old["fill_holes"]) == ("census", 8, None, False)
    assert "previous default" in methods["sc-census-8"].description
    assert methods["sc-census-3"].params["cost"] == "census" and methods["sc-census-3"].params["paths"] == default.paths
    assert methods["sc-8"].params["paths"] == 8 and methods["sc-8"].params["cost"] == default.cost
    indep = methods["sc-independent"].params
    assert (indep["lr_mode"], indep["paths"], indep["cost"]) == ("independent", default.paths, default.cost)
    sad = methods["sc-sad-8"].params
    assert (sad["cost"], sad["paths"], sad["lr_check"], sad["fill_holes"]) == ("sad", 8, None, False)
    assert [m.name for m in default_methods(["ocv-3way", "sc-8"])] == ["sc-8", "ocv-3way"]


def test_the_default_matcher_returns_output_and_measured_pixels():
    rng = np.random.default_rng(0)
    left = rng.integers(0, 255, (32, 64), dtype=np.uint8)
    right = np.roll(left, -4, axis=1)
    runner = next(m for m in stereo_classic_methods() if m.name == "sc-default").prepare(Setup(num_disparities=16))
    out, measured = output_views(runner(left, right), left.shape)
    assert out.dtype == np.float32 and out.shape == measured.shape == left.shape
    assert np.isfinite(out).all()  # holes filled (the default's fill_holes)
    assert (np.isfinite(measured) <= np.isfinite(out)).all()
    assert np.array_equal(out[np.isfinite(measured)], measured[np.isfinite(measured)])


def test_output_views_reads_arrays_tuples_and_maps():
    a = np.zeros((2, 3), np.float32)
    m = a.copy()
    m[0, 0] = np.nan
    assert output_views(a)[0] is a and output_views(a)[1] is a
    assert output_views((a, m))[1] is m

    class Map:  # a DisparityMap: the measured pixels in disparity, the dense output in filled_disparity
        filled_disparity, disparity = a, m

    assert output_views(Map())[0] is a and output_views(Map())[1] is m


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ([1, 2], "must return an (H, W) float array"),
        ((np.zeros((2, 3), np.float32), np.zeros((3, 3), np.float32)), "measured must be a float array of shape (2, 3)"),
        (np.zeros((2, 3), np.int16), "output must be a float array"),
        ((np.full((2, 3), np.nan, np.float32), np.zeros((2, 3), np.float32)), "values where its output is unknown"),
    ],
)
def test_output_views_errors_name_what_is_wrong(value, message):
    with pytest.raises(RuntimeError, match=message.replace("(", r"\(").replace(")", r"\)")):
        output_views(value, (2, 3))
