"""Tests for stereo_classic.fusion.localize: accuracy on planted objects, statuses, seeds, error paths."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stereo_classic.fusion import STATUSES, FusionInputError, LocalizedObjects, localize
from tests.helpers.scenes import disparity_of, make_rig, planted_scene


def _noisy(gt, rng, sigma=0.25, outliers=0.05, holes=0.05):
    d = gt + rng.normal(0, sigma, gt.shape).astype(np.float32)
    out = rng.random(gt.shape) < outliers
    d[out] = rng.uniform(0, 60, out.sum())
    d[rng.random(gt.shape) < holes] = np.nan
    return d


# --- smoke -------------------------------------------------------------------------------------------

def test_constant_disparity_gives_exact_distance():
    rig = make_rig(40, 30, focal_px=500.0, baseline_m=0.1)
    objs = localize(np.array([[10, 5, 30, 25]]), np.full((30, 40), 10.0, np.float32), rig)
    assert objs.status == ("ok",)
    assert objs.distance_m[0] == pytest.approx(5.0, rel=1e-12)
    assert objs.inlier_ratio[0] == 1.0 and objs.spread_m[0] == pytest.approx(0.0, abs=1e-12)


def test_accepts_a_disparity_map_like_object_and_detections_like_object():
    class DMap:
        disparity = np.full((30, 40), 20.0, np.float32)

    class Dets:
        xyxy = np.array([[0, 0, 40, 30]], np.float32)
        confidence = np.array([0.9], np.float32)
        class_id = np.array([2])
        labels = ["car"]

    objs = localize(Dets(), DMap(), make_rig(40, 30, focal_px=400.0, baseline_m=0.5))
    assert objs.labels == ("car",) and objs.confidence[0] == pytest.approx(0.9)
    assert objs.distance_m[0] == pytest.approx(10.0)


# --- accuracy on planted objects -----------------------------------------------------------------------

@pytest.mark.parametrize("z_box, z_wall", [(1.5, 6.0), (3.0, 8.0), (6.0, 9.0), (10.0, 30.0)])
def test_planted_object_within_one_percent(z_box, z_wall):
    rng = np.random.default_rng(1)
    _, _, gt, rig = planted_scene(z_box=z_box, z_wall=z_wall)
    box = np.array([[80, 50, 160, 110]], np.float32)
    objs = localize(box, _noisy(gt, rng), rig, rng=3)
    assert objs.status == ("ok",)
    assert objs.distance_m[0] == pytest.approx(z_box, rel=0.01)
    assert objs.xyz[0, 2] == objs.distance_m[0]


@pytest.mark.parametrize("object_fraction", [0.3, 0.4, 0.45])
def test_background_never_wins_even_when_it_fills_most_of_the_box(object_fraction):
    """The detection box is much larger than the object; the wall fills most of the (shrunk) box."""
    rng = np.random.default_rng(2)
    width, height = 300, 200
    # A centred object covering `object_fraction` of the shrunk box (shrink 0.2 of a 200x150 box).
    bw, bh = 200 * 0.8, 150 * 0.8
    side = math.sqrt(object_fraction * bw * bh / (bw / bh))
    ow, oh = side * bw / bh, side
    cx, cy = 150, 100
    obj = (int(cx - ow / 2), int(cy - oh / 2), int(cx + ow / 2), int(cy + oh / 2))
    _, _, gt, rig = planted_scene(width=width, height=height, z_box=2.5, z_wall=5.0, box=obj)
    det = np.array([[50, 25, 250, 175]], np.float32)
    d = _noisy(gt, rng)
    objs = localize(det, d, rig)
    inside = gt[40:160, 70:230]
    assert (inside == gt.min()).mean() > 0.5  # the wall really fills most of the box
    assert objs.status == ("ok",)
    assert objs.distance_m[0] == pytest.approx(2.5, rel=0.01)
    # The median is pulled to the background there, which is why RANSAC is used.
    med = localize(det, d, rig, method="median")
    assert med.distance_m[0] > 2.5 * 1.2


def test_largest_set_wins_over_a_small_nearer_clutter():
    """A thin near occluder (a pole) inside a car's box must not become the car's distance."""
    rng = np.random.default_rng(4)
    _, _, gt, rig = planted_scene(z_box=6.0, z_wall=20.0, box=(40, 20, 200, 140))
    pole = disparity_of(2.0, rig)
    gt = gt.copy()
    gt[:, 110:122] = pole  # ~10 % of the shrunk box
    objs = localize(np.array([[40, 20, 200, 140]]), _noisy(gt, rng), rig)
    assert objs.distance_m[0] == pytest.approx(6.0, rel=0.01)


def test_tie_goes_to_the_nearer_set():
    rig = make_rig(40, 20, focal_px=500.0, baseline_m=0.1)
    d = np.full((20, 40), 10.0, np.float32)
    d[:, 20:] = 25.0  # exactly half near (25 px) and half far (10 px)
    objs = localize(np.array([[0, 0, 40, 20]]), d, rig, box_shrink=0.0, near_support=1.0, centre_sigma=0)
    assert objs.distance_m[0] == pytest.approx(500 * 0.1 / 25.0)


def test_distance_is_the_median_depth_of_the_set_not_its_mean():
    """A surface at d = 20 px with a tail of background values within the band behind it: depth goes as 1 / d, so
    the mean depth of the set sits behind the surface; the distance is its median depth."""
    rig = make_rig(40, 20, focal_px=500.0, baseline_m=0.2)  # f B = 100 px m: d = 20 px is 5 m
    rng = np.random.default_rng(3)
    d = np.full((20, 40), 20.0, np.float32) + rng.normal(0, 0.05, (20, 40)).astype(np.float32)
    d[:, :12] = 19.3 + rng.normal(0, 0.05, (20, 12)).astype(np.float32)  # within tolerance_px, 0.18 m behind
    objs = localize(np.array([[0, 0, 40, 20]]), d, rig, box_shrink=0.0, centre_sigma=0, grow_density=0.0)
    z = 100.0 / d.astype(np.float64)
    assert objs.inliers[0] == d.size  # the whole box is one set
    assert objs.distance_m[0] == pytest.approx(float(np.median(z)), rel=1e-6)
    assert objs.distance_m[0] < float(z.mean()) - 0.02


def test_strict_largest_set_with_near_support_one():
    rig = make_rig(40, 20, focal_px=500.0, baseline_m=0.1)
    d = np.full((20, 40), 10.0, np.float32)
    d[:, 30:] = 25.0  # near set has a third of the far set's support
    objs = localize(np.array([[0, 0, 40, 20]]), d, rig, box_shrink=0.0, near_support=1.0, centre_sigma=0)
    assert objs.distance_m[0] == pytest.approx(5.0)
    # the near set fills the box's right quarter: an occluder by default, the object with the rule off
    objs = localize(np.array([[0, 0, 40, 20]]), d, rig, box_shrink=0.0, near_support=0.3, centre_sigma=0,
                    occluder_offset=0.5)
    assert objs.distance_m[0] == pytest.approx(2.0) and not objs.occluded[0]
    objs = localize(np.array([[0, 0, 40, 20]]), d, rig, box_shrink=0.0, near_support=0.3, centre_sigma=0)
    assert objs.distance_m[0] == pytest.approx(5.0) and objs.occluded[0] and objs.status == ("ok",)


def test_xyz_is_the_median_point_of_the_inlier_points_from_rig_points():
    rng = np.random.default_rng(5)
    _, _, gt, rig = planted_scene(z_box=3.0, z_wall=8.0, box=(20, 30, 90, 100))
    d = _noisy(gt, rng, outliers=0.0, holes=0.0)
    objs = localize(np.array([[20, 30, 90, 100]]), d, rig, tolerance_px=100.0, box_shrink=0.2,
                    depth_range=(0.1, 100.0))
    pts = rig.points(d)[37:93, 27:83].reshape(-1, 3)  # shrunk box: 20 + 0.1 * 70 = 27, ...
    np.testing.assert_allclose(objs.xyz[0], np.median(pts, axis=0), rtol=1e-4)
    assert objs.xyz[0, 0] < 0 and objs.xyz[0, 1] < 0  # left of and above the image centre
    assert objs.inliers[0] == pts.shape[0] and objs.valid_pixels[0] == pts.shape[0]


def test_same_seed_same_output_and_large_boxes_use_the_rng():
    rng = np.random.default_rng(6)
    _, _, gt, rig = planted_scene(z_box=4.0, z_wall=12.0)
    d = _noisy(gt, rng)
    box = np.array([[60, 30, 180, 130]])
    a = localize(box, d, rig, rng=11, max_iterations=16)
    b = localize(box, d, rig, rng=11, max_iterations=16)
    assert json.dumps(a.to_json()) == json.dumps(b.to_json())
    assert a.distance_m[0] == pytest.approx(4.0, rel=0.01)
    gen = localize(box, d, rig, rng=np.random.default_rng(11), max_iterations=16)
    assert gen.distance_m[0] == a.distance_m[0]


# --- statuses ----------------------------------------------------------------------------------------

def test_statuses_say_why_instead_of_a_made_up_number():
    rig = make_rig(60, 40, focal_px=500.0, baseline_m=0.1)
    d = np.full((40, 60), np.nan, np.float32)
    d[:, 30:] = 0.1  # 500 m: beyond the default 80 m
    d[30:, :10] = 10.0
    rng = np.random.default_rng(0)
    d[:20, :10] = rng.uniform(1, 50, (20, 10))  # noise: no consistent set of 20
    boxes = np.array([
        [100, 100, 120, 120],  # outside the image
        [12, 0, 28, 20],       # all unknown
        [35, 5, 55, 35],       # all at 500 m
        [10, 3, 25, 3],        # zero height
        [0, 0, 10, 20],        # noise
    ], np.float32)
    objs = localize(boxes, d, rig, min_pixels=20, box_shrink=0.0, tolerance_px=0.05)
    assert objs.status == ("empty_box", "too_few_depth_pixels", "out_of_range", "empty_box", "no_consensus")
    assert np.all(np.isnan(objs.distance_m)) and np.all(np.isnan(objs.xyz))
    assert set(objs.status) <= set(STATUSES)
    rows = json.loads(json.dumps(objs.to_json(), allow_nan=False))
    assert rows[2]["distance_m"] is None and rows[2]["xyz_m"] is None and rows[2]["status"] == "out_of_range"
    assert "distance unknown (out of range)" in objs.format_table()


def test_empty_detections():
    rig = make_rig(10, 10)
    objs = localize(np.zeros((0, 4)), np.ones((10, 10), np.float32), rig)
    assert len(objs) == 0 and objs.to_json() == [] and objs.xyz.shape == (0, 3)
    assert len(LocalizedObjects.empty()) == 0


# --- dtypes --------------------------------------------------------------------------------------------

def test_integer_disparity_is_accepted():
    rig = make_rig(20, 20, focal_px=100.0, baseline_m=1.0)
    objs = localize(np.array([[0, 0, 20, 20]]), np.full((20, 20), 50, np.int16), rig)
    assert objs.distance_m[0] == pytest.approx(2.0)


# --- error paths -------------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, name", [
    ({"method": "mean"}, "method"),
    ({"box_shrink": 1.0}, "box_shrink"),
    ({"box_shrink": -0.1}, "box_shrink"),
    ({"box_shrink": "x"}, "box_shrink"),
    ({"depth_range": (5.0, 1.0)}, "depth_range"),
    ({"depth_range": (0.0, math.inf)}, "depth_range"),
    ({"depth_range": 3}, "depth_range"),
    ({"min_pixels": 0}, "min_pixels"),
    ({"min_pixels": 2.5}, "min_pixels"),
    ({"tolerance_px": 0}, "tolerance_px"),
    ({"tolerance_px": math.nan}, "tolerance_px"),
    ({"near_support": 0}, "near_support"),
    ({"max_clusters": 0}, "max_clusters"),
    ({"rng": -1}, "rng"),
    ({"rng": "seed"}, "rng"),
])
def test_bad_parameters_name_the_parameter(kwargs, name):
    rig = make_rig(10, 10)
    with pytest.raises(FusionInputError, match=name):
        localize(np.array([[0, 0, 5, 5]]), np.ones((10, 10), np.float32), rig, **kwargs)


@pytest.mark.parametrize("dets, disp, match", [
    (np.array([[0, 0, 5]]), np.ones((10, 10)), "detections"),
    (np.array([[5, 0, 0, 5]]), np.ones((10, 10)), "x1 >= x0"),
    (np.array([[0, 0, np.nan, 5]]), np.ones((10, 10)), "finite"),
    ("boxes", np.ones((10, 10)), "detections"),
    (np.array([[0, 0, 5, 5]]), np.ones((10, 10, 3)), "disparity_map"),
    (np.array([[0, 0, 5, 5]]), np.ones((0, 0)), "disparity_map"),
    (np.array([[0, 0, 5, 5]]), np.array([["a"] * 10] * 10), "disparity_map"),
    (np.array([[0, 0, 5, 5]]), np.ones((12, 10)), "image_size"),
])
def test_bad_inputs_name_the_parameter(dets, disp, match):
    with pytest.raises(FusionInputError, match=match):
        localize(dets, disp, make_rig(10, 10))


def test_bad_rig():
    with pytest.raises(FusionInputError, match="rig"):
        localize(np.zeros((0, 4)), np.ones((10, 10)), object())
    rig = _stand_in(make_rig(10, 10))
    rig.baseline_m = 0.0
    with pytest.raises(FusionInputError, match="baseline_m"):
        localize(np.zeros((0, 4)), np.ones((10, 10)), rig)


def _stand_in(rig, **changes):
    """A plain namespace with the attributes localize reads from a rig (a RectifiedRig stand-in)."""
    attrs = dict(focal_px=rig.focal_px, baseline_m=rig.baseline_m, doffs=rig.doffs, cx_left=rig.cx_left, cy=rig.cy,
                 image_size=rig.image_size)
    return SimpleNamespace(**{**attrs, **changes})


def test_any_rig_like_object_gives_the_same_result_as_the_rectified_rig():
    """`rig` is a calib.RectifiedRig or anything with its attributes; image_size is then optional."""
    rng = np.random.default_rng(8)
    _, _, gt, rig = planted_scene(rig=make_rig(240, 160, doffs=7.0))
    d = _noisy(gt, rng)
    box = np.array([[80, 50, 160, 110], [0, 0, 240, 160]])
    ref = localize(box, d, rig, rng=2)
    for other in (_stand_in(rig), SimpleNamespace(**{k: v for k, v in vars(_stand_in(rig)).items()
                                                     if k != "image_size"})):
        got = localize(box, d, other, rng=2)
        np.testing.assert_array_equal(got.xyz, ref.xyz)
        assert got.status == ref.status == ("ok", "ok")
    with pytest.raises(FusionInputError, match="image_size"):
        localize(box, d, _stand_in(rig, image_size=(100, 100)))


# --- property test: any input gives a well-formed result or the documented error ------------------------

@st.composite
def _cases(draw):
    h = draw(st.integers(1, 40))
    w = draw(st.integers(1, 40))
    seed = draw(st.integers(0, 2**16))
    rng = np.random.default_rng(seed)
    kind = draw(st.sampled_from(["uniform", "const", "nan", "inf", "neg", "huge"]))
    d = rng.uniform(-5, 80, (h, w)).astype(np.float32)
    if kind == "const":
        d[:] = draw(st.floats(-10, 1000, allow_nan=False))
    elif kind == "nan":
        d[rng.random((h, w)) < 0.7] = np.nan
    elif kind == "inf":
        d[rng.random((h, w)) < 0.3] = np.inf
    elif kind == "neg":
        d = -np.abs(d)
    elif kind == "huge":
        d[:] = 1e30
    n = draw(st.integers(0, 4))
    boxes = []
    for _ in range(n):
        x0 = draw(st.floats(-50, 60))
        y0 = draw(st.floats(-50, 60))
        boxes.append([x0, y0, x0 + draw(st.floats(0, 80)), y0 + draw(st.floats(0, 80))])
    params = dict(
        box_shrink=draw(st.floats(0, 0.99)),
        min_pixels=draw(st.integers(1, 50)),
        tolerance_px=draw(st.floats(1e-3, 50)),
        near_support=draw(st.floats(0.01, 1.0)),
        method=draw(st.sampled_from(["ransac", "median"])),
    )
    focal = draw(st.floats(1.0, 5000.0))
    base = draw(st.floats(1e-3, 2.0))
    doffs = draw(st.floats(-20.0, 50.0))
    return d, np.array(boxes, np.float64).reshape(-1, 4), make_rig(w, h, focal_px=focal, baseline_m=base, doffs=doffs), params


@settings(max_examples=450, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(_cases())
def test_property_well_formed_result(case):
    d, boxes, rig, params = case
    objs = localize(boxes, d, rig, rng=0, **params)
    assert len(objs) == len(boxes)
    for i, s in enumerate(objs.status):
        assert s in STATUSES
        if s == "ok":
            z = objs.distance_m[i]
            assert math.isfinite(z) and 0.3 <= z <= 80.0
            assert np.all(np.isfinite(objs.xyz[i]))
            if params["method"] == "ransac":
                assert objs.inliers[i] >= params["min_pixels"]
                assert 0 < objs.inlier_ratio[i] <= 1
            else:  # the median's "inliers" are the votes within tolerance_px of it: possibly none
                assert 0 <= objs.inlier_ratio[i] <= 1
        else:
            assert math.isnan(objs.distance_m[i])
    json.dumps(objs.to_json(), allow_nan=False)


def test_grow_density_merges_a_slanted_surface():
    """A surface slanting from 3 to 5 m: without growth one 2 px slice, with growth all of it."""
    rig = make_rig(200, 60, focal_px=500.0, baseline_m=0.2)
    z = np.linspace(3.0, 5.0, 200)[None, :].repeat(60, axis=0)
    d = (100.0 / z).astype(np.float32)
    box = np.array([[0, 0, 200, 60]])
    plain = localize(box, d, rig, box_shrink=0.0, centre_sigma=0, grow_density=0)
    grown = localize(box, d, rig, box_shrink=0.0, centre_sigma=0, grow_density=0.2)
    # 12 000 votes > max_samples: the sets are found on a sample; growth stops within one step of the ends
    assert grown.inliers[0] >= 0.95 * d.size and plain.inliers[0] < d.size / 5
    assert grown.distance_m[0] == pytest.approx(z.mean(), rel=0.01)


def test_xyz_matches_calib_rectified_rig_points_with_doffs():
    """The position uses the same geometry as calib.RectifiedRig.points (doffs and principal point included)."""
    from calib import RectifiedRig

    rig = RectifiedRig(focal_px=900.0, cx_left=50.0, cx_right=81.0, cy=35.0, baseline_m=0.2, image_size=(120, 80))
    rng = np.random.default_rng(9)
    d = (40.0 + rng.normal(0, 0.2, (80, 120))).astype(np.float32)
    objs = localize(np.array([[10, 10, 110, 70]]), d, rig, box_shrink=0.0, tolerance_px=50.0, centre_sigma=0,
                    depth_range=(0.1, 100.0))
    pts = rig.points(d)[10:70, 10:110].reshape(-1, 3)
    np.testing.assert_allclose(objs.xyz[0], np.median(pts, axis=0), rtol=1e-5)
    assert objs.distance_m[0] == pytest.approx(900 * 0.2 / (40.0 + 31.0), rel=1e-3)


# --- an occluder does not take the label (issue #15 item 4) -----------------------------------------------

def _occluder_scene(near_rows: slice, near_cols: slice = slice(None)):
    """A 50x40 box at 10 px (5 m with f 500, B 0.1), with a block at 40 px (1.25 m) where the slices say."""
    rig = make_rig(50, 40, focal_px=500.0, baseline_m=0.1)
    d = np.full((40, 50), 10.0, np.float32)
    d[near_rows, near_cols] = 40.0
    return d, rig


def test_a_near_set_entering_from_the_box_edge_is_an_occluder():
    d, rig = _occluder_scene(slice(24, 40))  # the bottom 40 %: a hand in front of a chair
    objs = localize(np.array([[0, 0, 50, 40]]), d, rig, box_shrink=0.0, centre_sigma=0)
    assert objs.status == ("ok",) and objs.occluded.tolist() == [True]
    assert objs.distance_m[0] == pytest.approx(5.0)  # the set covering the object, not the hand's 1.25 m
    assert objs.to_json()[0]["occluded"] is True
    assert "behind an occluder" in objs.format_table()
    assert objs[objs.ok].occluded.tolist() == [True]  # selection keeps the flag


def test_a_central_near_object_in_front_of_a_larger_background_still_wins():
    d, rig = _occluder_scene(slice(12, 28), slice(15, 35))  # centred, a fifth of the box: the detected object
    objs = localize(np.array([[0, 0, 50, 40]]), d, rig, box_shrink=0.0, centre_sigma=0, near_support=0.15)
    assert objs.distance_m[0] == pytest.approx(1.25) and not objs.occluded[0]


@pytest.mark.parametrize(("overrides", "expected"), [
    ({"occluder_offset": 0.5}, 1.25),   # the rule off: the near set wins as before
    ({"occluder_ratio": 5.0}, 1.25),    # 4x nearer is not enough for a ratio of 5
    ({}, 5.0),
])
def test_occluder_parameters(overrides, expected):
    d, rig = _occluder_scene(slice(24, 40))
    objs = localize(np.array([[0, 0, 50, 40]]), d, rig, box_shrink=0.0, centre_sigma=0, **overrides)
    assert objs.distance_m[0] == pytest.approx(expected)


@pytest.mark.parametrize(("name", "value"), [("occluder_ratio", 0.5), ("occluder_ratio", float("nan")),
                                             ("occluder_offset", 0.0), ("occluder_offset", 0.6)])
def test_occluder_parameters_are_checked(name, value):
    from stereo_classic.fusion import FusionParams

    with pytest.raises(FusionInputError, match=f"`{name}`"):
        FusionParams(**{name: value})


def test_pov_hands_chair_is_not_the_hand(shared_data, yolox_nano):
    """In OAK-D `pov_hands` the hand in front of the chair used to become "chair 0.48 m"."""
    from detectors import OnnxDetector
    from stereo_classic.datasets import load_scene
    from stereo_classic.pipeline import Localizer

    scene = load_scene(shared_data / "oakd" / "pov_hands")
    with Localizer(scene.rig, OnnxDetector(yolox_nano), {"num_disparities": 128}) as loc:
        objs = loc(scene.left, scene.right).objects
    chair = objs[np.array([label == "chair" for label in objs.labels])]
    assert len(chair) == 1 and chair.status == ("ok",) and chair.occluded[0]
    assert 1.3 < chair.distance_m[0] < 2.0  # the chair behind the hand (the hand is at 0.48 m)


def test_nearest_surface_is_the_tenth_percentile_of_the_inliers_depth():
    """A surface slanted in depth (disparity 20.0 .. 21.9 px across the box): the nearest surface is nearer than the
    centroid and equals the 10th percentile of the inliers' depth; no distance, no nearest surface."""
    rig = make_rig(40, 20, focal_px=500.0, baseline_m=0.1)
    d = np.tile(np.linspace(20.0, 21.9, 40, dtype=np.float32), (20, 1))
    objs = localize(np.array([[0, 0, 40, 20]]), d, rig, box_shrink=0.0, tolerance_px=3.0, centre_sigma=0)
    z = 500 * 0.1 / d.astype(np.float64)
    assert objs.status == ("ok",)
    assert objs.nearest_m[0] == pytest.approx(np.percentile(z, 10), rel=1e-6)
    assert objs.nearest_m[0] < objs.distance_m[0]
    assert objs.to_json()[0]["nearest_m"] == pytest.approx(objs.nearest_m[0], abs=1e-3)
    gone = objs.with_status([0], "beyond_range")
    assert np.isnan(gone.nearest_m[0]) and np.isnan(objs[[0]].nearest_m).sum() == 0
