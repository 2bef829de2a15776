"""stereo_classic.fusion.contact: the disparity's uncertainty and the ground-contact check (issue 31)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from detectors import COCO_CLASSES, Detections
from stereo_classic.fusion import localize
from stereo_classic.fusion.contact import SUBPIXEL_SIGMA_PX, disparity_sigma, ground_contact
from tests.helpers.scenes import make_rig

H, W = 200, 300
SLOPE = 0.33  # px of disparity per row: a camera 1.65 m above a level road with a 0.54 m baseline
HORIZON = 80


def _road_frame(object_d: float, box=(120, 100, 180, 140)) -> np.ndarray:
    """A level road (d = SLOPE * (v - HORIZON) below the horizon, far wall above) and a fronto-parallel object of
    disparity ``object_d`` filling ``box``, standing on the road only when ``object_d`` is the road's at its
    bottom row."""
    v = np.arange(H, dtype=np.float32)[:, None]
    disp = np.where(v > HORIZON, SLOPE * (v - HORIZON), 2.0).astype(np.float32) * np.ones((1, W), np.float32)
    x0, y0, x1, y1 = box
    disp[y0:y1, x0:x1] = object_d
    return disp


def _dets(box, label="car"):
    return Detections(np.array([box], np.float32), np.array([0.9], np.float32),
                      np.array([COCO_CLASSES.index(label)]))


def test_sigma_is_the_subpixel_floor_plus_the_spread_over_sqrt_n():
    assert disparity_sigma(np.full(100, 7.0)) == pytest.approx(SUBPIXEL_SIGMA_PX)
    values = np.random.default_rng(0).normal(10.0, 1.0, 400)
    assert disparity_sigma(values) == pytest.approx(math.hypot(SUBPIXEL_SIGMA_PX, 1.0 / 20.0), rel=0.1)
    assert math.isnan(disparity_sigma(np.zeros(0)))


def test_contact_reads_the_road_below_the_box():
    box = (120, 100, 180, 140)
    d_foot = SLOPE * (139.5 - HORIZON)  # the road at the box's bottom edge (y1 = 140: row 139's lower edge)
    got = ground_contact(_road_frame(d_foot, box), np.array(box, float), 20)
    assert got is not None and got[0] == pytest.approx(d_foot, abs=0.05) and got[1] > 0


def test_no_contact_where_the_strip_below_is_no_ground():
    box = (120, 100, 180, 140)
    disp = _road_frame(10.0, box)
    disp[140:170, 100:200] = 25.0  # a nearer vertical surface hides the object's foot: no slope
    assert ground_contact(disp, np.array(box, float), 20) is None
    assert ground_contact(disp, np.array((120, 100, 180, H), float), 20) is None  # box at the image's bottom


def test_distance_and_contact_agree_ok_with_sigma_in_the_json():
    rig = make_rig(W, H, focal_px=1000.0, baseline_m=0.5)
    box = (120, 100, 180, 140)
    d_foot = SLOPE * (139.5 - HORIZON)
    objs = localize(_dets(box), _road_frame(d_foot, box), rig, rng=0)
    assert objs.status == ("ok",)
    z = 500.0 / d_foot
    assert objs.distance_m[0] == pytest.approx(z, rel=1e-3)
    assert objs.distance_sigma_m[0] == pytest.approx(z * z / 500.0 * SUBPIXEL_SIGMA_PX, rel=0.05)
    assert objs.to_json()[0]["distance_sigma_m"] == pytest.approx(objs.distance_sigma_m[0], abs=1e-3)


def test_distance_far_behind_the_contact_is_reported_as_a_disagreement():
    """The failure of issue 31: the box's set says much farther than where the object stands on the road."""
    rig = make_rig(W, H, focal_px=1000.0, baseline_m=0.5)
    box = (120, 100, 180, 140)
    d_foot = SLOPE * (139.5 - HORIZON)  # 19.6 px: 25.5 m
    disp = _road_frame(0.5 * d_foot, box)  # the set reads twice as far
    objs = localize(_dets(box), disp, rig, rng=0)
    assert objs.status == ("estimates_disagree",) and np.isnan(objs.distance_m[0])
    assert np.isnan(objs.distance_sigma_m[0]) and objs.to_json()[0]["distance_m"] is None
    assert localize(_dets(box), disp, rig, rng=0, ground_contact=False).status == ("ok",)  # before: ok
    assert localize(_dets(box, "chair"), disp, rig, rng=0).status == ("ok",)  # not a ground class: no check


def test_a_box_placed_too_high_reads_the_object_not_what_lies_behind_it():
    """Issue 31's failure: the box's upper part holds the background (more pixels than the object), the object
    stands in its lower part. A person or vehicle reaches the box's bottom; the background set does not."""
    rig = make_rig(W, H, focal_px=1000.0, baseline_m=0.5)
    disp = np.full((H, W), 8.0, np.float32)  # trees 62.5 m away
    disp[118:150, 110:190] = 14.0  # the car, 35.7 m, only in the lower 40 % of its box
    box = (110, 70, 190, 150)
    assert localize(_dets(box, "potted plant"), disp, rig, rng=0).distance_m[0] == pytest.approx(62.5, rel=1e-3)
    assert localize(_dets(box), disp, rig, rng=0, ground_contact=False).distance_m[0] == pytest.approx(62.5, rel=1e-3)
    objs = localize(_dets(box), disp, rig, rng=0)
    assert objs.status == ("ok",) and objs.distance_m[0] == pytest.approx(500.0 / 14.0, rel=1e-3)
    disp[118:150, 110:150] = 8.0  # the nearer set only on the box's left side: an occluder's place, not taken
    assert localize(_dets(box), disp, rig, rng=0).distance_m[0] == pytest.approx(62.5, rel=1e-3)
