"""benchmarks.metrics on small hand-made arrays with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from benchmarks.metrics import (
    error_metrics,
    mean_metrics,
    scene_metrics,
    visible_in_both,
)

NAN = np.nan
INF = np.inf


def test_hand_made_known_answers():
    gt = np.array([[1.0, 2.0, 3.0, 4.0, 10.0, NAN]], np.float32)
    pred = np.array([[1.0, 2.6, 5.5, NAN, 13.5, 7.0]], np.float32)
    # errors on counted pixels: 0, 0.6, 2.5, -, 3.5 ; one unknown (x=3); x=5 has no GT and never counts
    m = error_metrics(pred, gt)
    assert m["all"]["n"] == 5 and m["valid"]["n"] == 4
    assert m["all"]["bad0.5"] == pytest.approx(100 * 4 / 5)   # 0.6, 2.5, 3.5 + unknown
    assert m["all"]["bad1"] == pytest.approx(100 * 3 / 5)
    assert m["all"]["bad2"] == pytest.approx(100 * 3 / 5)
    assert m["all"]["bad4"] == pytest.approx(100 * 1 / 5)     # only the unknown
    assert m["valid"]["bad0.5"] == pytest.approx(100 * 3 / 4)
    assert m["valid"]["bad2"] == pytest.approx(100 * 2 / 4)
    assert m["valid"]["bad4"] == pytest.approx(0.0)
    assert m["valid"]["epe"] == pytest.approx((0 + 0.6 + 2.5 + 3.5) / 4, abs=1e-6)
    assert m["valid"]["rms"] == pytest.approx(math.sqrt((0.36 + 6.25 + 12.25) / 4), abs=1e-6)
    assert m["all"]["epe"] is None and m["all"]["rms"] is None
    # D1: error > 3 px AND > 5 % of the true disparity: only x=4 (3.5 > 3 and 3.5 > 0.5)
    assert m["valid"]["d1"] == pytest.approx(100 * 1 / 4)
    assert m["all"]["d1"] == pytest.approx(100 * 2 / 5)
    assert m["all"]["density"] == pytest.approx(100 * 4 / 5) == m["valid"]["density"]


def test_d1_needs_both_conditions():
    gt = np.array([[100.0, 100.0, 2.0]], np.float32)
    pred = np.array([[104.0, 106.0, 5.5]], np.float32)
    # 4 px on 100: > 3 px but not > 5 px (5 %): good; 6 px on 100: bad; 3.5 px on 2: bad
    assert error_metrics(pred, gt)["valid"]["d1"] == pytest.approx(100 * 2 / 3)


def test_inf_is_unknown_in_both_inputs():
    gt = np.array([[1.0, INF, -INF, 2.0]], np.float32)
    pred = np.array([[1.0, 1.0, 1.0, INF]], np.float32)
    m = error_metrics(pred, gt)
    assert m["all"]["n"] == 2 and m["valid"]["n"] == 1
    assert m["all"]["bad2"] == pytest.approx(50.0)
    assert m["valid"]["bad2"] == pytest.approx(0.0)
    assert m["valid"]["epe"] == pytest.approx(0.0)


def test_nothing_counted_gives_none_not_nan():
    gt = np.full((3, 4), NAN, np.float32)
    m = error_metrics(np.zeros((3, 4), np.float32), gt)
    for view in ("all", "valid"):
        assert m[view]["n"] == 0
        assert all(m[view][k] is None for k in ("bad0.5", "bad1", "bad2", "bad4", "d1", "density", "epe", "rms"))


def test_all_unknown_prediction():
    gt = np.ones((2, 3), np.float32)
    m = error_metrics(np.full((2, 3), NAN, np.float32), gt)
    assert m["all"]["bad2"] == 100.0 and m["all"]["d1"] == 100.0 and m["all"]["density"] == 0.0
    assert m["valid"]["bad2"] is None and m["valid"]["epe"] is None


def test_empty_mask_and_mask_region():
    gt = np.array([[1.0, 1.0, 1.0, 1.0]], np.float32)
    pred = np.array([[9.0, 1.0, NAN, 1.0]], np.float32)
    empty = error_metrics(pred, gt, np.zeros((1, 4), bool))
    assert empty["all"]["n"] == 0 and empty["all"]["bad2"] is None
    only_right = error_metrics(pred, gt, np.array([[False, False, True, True]]))
    assert only_right["all"]["bad2"] == pytest.approx(50.0)
    assert only_right["valid"]["bad2"] == pytest.approx(0.0)


def test_scene_metrics_border_band_and_nonocc():
    gt = np.full((2, 8), 3.0, np.float32)
    pred = gt.copy()
    pred[:, :4] = NAN          # the invalid left border OpenCV leaves
    pred[0, 6] = 10.0          # one gross error outside the band, in an occluded pixel
    nonocc = np.ones((2, 8), bool)
    nonocc[0, 6] = False
    m = scene_metrics(pred, gt, nonocc_mask=nonocc, max_disparity=4)
    assert set(m) == {"full", "nonocc", "border"}
    assert m["border"]["all"]["n"] == 8
    assert m["border"]["all"]["bad2"] == 100.0 and m["border"]["all"]["density"] == 0.0
    assert m["border"]["valid"]["bad2"] is None
    assert m["full"]["all"]["bad2"] == pytest.approx(100 * 9 / 16)
    assert m["full"]["valid"]["bad2"] == pytest.approx(100 * 1 / 8)
    assert m["nonocc"]["valid"]["bad2"] == pytest.approx(0.0)
    assert m["nonocc"]["all"]["n"] == 15


def test_scene_metrics_without_mask_or_band():
    gt = np.ones((2, 2), np.float32)
    assert set(scene_metrics(gt, gt)) == {"full"}


@pytest.mark.parametrize(
    ("pred", "gt", "mask", "word"),
    [
        (np.zeros((2, 3)), np.zeros((3, 2)), None, "shape"),
        (np.zeros(4), np.zeros(4), None, "2-D"),
        (np.zeros((2, 2), "U1"), np.zeros((2, 2)), None, "dtype"),
        (np.zeros((2, 2)), np.zeros((2, 2)), np.ones((2, 2), np.uint8), "boolean"),
        (np.zeros((2, 2)), np.zeros((2, 2)), np.ones((3, 2), bool), "mask"),
    ],
)
def test_bad_input_names_the_parameter(pred, gt, mask, word):
    with pytest.raises(ValueError, match=word):
        error_metrics(pred, gt, mask)


def test_scene_metrics_bad_band():
    with pytest.raises(ValueError, match="max_disparity"):
        scene_metrics(np.zeros((2, 2)), np.zeros((2, 2)), max_disparity=-1)


def test_mean_metrics_ignores_none_and_sums_n():
    a = {"all": {"bad2": 10.0, "epe": None, "n": 4}}
    b = {"all": {"bad2": 30.0, "epe": None, "n": 6}}
    c = {"all": {"bad2": None, "epe": None, "n": 0}}
    assert mean_metrics([a, b, c]) == {"all": {"bad2": 20.0, "epe": None, "n": 10}}
    assert mean_metrics([]) == {}


@settings(max_examples=240, deadline=None)
@given(
    hnp.arrays(np.float32, st.tuples(st.integers(1, 6), st.integers(1, 6)),
               elements=st.one_of(st.floats(-50, 50, width=32), st.just(np.nan), st.just(np.inf))),
    st.data(),
)
def test_property_well_formed(gt, data):
    pred = data.draw(hnp.arrays(np.float32, gt.shape, elements=st.one_of(st.floats(-50, 50, width=32), st.just(np.nan), st.just(-np.inf))))
    m = error_metrics(pred, gt)
    n_known = int(np.isfinite(gt).sum())
    assert m["all"]["n"] == n_known
    for view in ("all", "valid"):
        for key in ("bad0.5", "bad1", "bad2", "bad4", "d1", "density"):
            v = m[view][key]
            assert v is None or 0.0 <= v <= 100.0
        if m[view]["n"]:
            assert m[view]["bad0.5"] >= m[view]["bad1"] >= m[view]["bad2"] >= m[view]["bad4"]
    if m["valid"]["n"]:
        assert m["valid"]["rms"] >= m["valid"]["epe"] - 1e-9 >= -1e-9
        assert m["all"]["bad2"] >= m["valid"]["bad2"] * m["valid"]["n"] / n_known - 1e-9


def test_visible_in_both_hides_what_a_nearer_surface_covers_and_what_leaves_the_image():
    # background 2 px, a block 6 px at x 10..14: the block covers right columns 4..8, which the background
    # pixels x 6..10 would land on (x - 2); x 0, 1 land left of the right image
    gt = np.full((3, 20), 2.0, np.float32)
    gt[:, 10:15] = 6.0
    gt[2, 3] = NAN  # no ground truth: never visible, never a surface
    v = visible_in_both(gt)
    hidden = [x for x in range(20) if not v[0, x]]
    assert hidden == [0, 1, 6, 7, 8, 9]  # x=10 is the block itself (6 px: lands on 4)
    assert not v[2, 3] and v[2, 4]
    # a surface within the tolerance does not hide: a slant of 0.5 px per pixel
    slant = np.tile(np.arange(20, dtype=np.float32)[None, :] * 0.5 + 1.0, (2, 1))
    assert visible_in_both(slant)[:, 2:].all()
    # fractional landing: either column around it counts
    gt2 = np.full((1, 12), 1.5, np.float32)
    gt2[0, 8] = 5.0  # lands on 3.0; background pixel x=4.5 - 1.5 -> 3.0 would need x=4.5: x=4 (2.5) and x=5 (3.5)
    assert not visible_in_both(gt2)[0, 4] and not visible_in_both(gt2)[0, 5] and visible_in_both(gt2)[0, 6]


@pytest.mark.parametrize("tol", [-1.0, NAN, INF])
def test_visible_in_both_rejects_a_bad_tolerance(tol):
    with pytest.raises(ValueError, match="tolerance"):
        visible_in_both(np.ones((2, 2), np.float32), tol)


def test_visible_in_both_agrees_with_the_datasets_occlusion_masks(shared_data):
    from benchmarks.scenes import load_scenes

    scenes = [s for s in load_scenes(shared_data, ["Adirondack", "Motorcycle"]) if s.nonocc_mask is not None]
    if not scenes:
        pytest.skip("no scene with an occlusion mask in the shared data")
    for scene in scenes:
        known = np.isfinite(scene.gt_disparity)
        v = visible_in_both(scene.gt_disparity)
        assert abs(v[known].mean() - scene.nonocc_mask[known].mean()) < 0.01, scene.name
        assert (v == scene.nonocc_mask)[known].mean() > 0.97, scene.name
