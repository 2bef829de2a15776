"""The up direction from the image's vertical lines: rendered poles at known pitch and roll, texture alone (no
estimate), bad input, and the OAK-D scenes (against their floors; the stairs frame looks up the flight)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import stereo_classic as sc
from stereo_classic.guide import GroundPlane, GuideInputError, GuideParams, fit_ground
from stereo_classic.guide.core import frame_points
from stereo_classic.guide.gravity import GRAVITY_TOLERANCE_DEG, Gravity, estimate_gravity
from tests.helpers import walk_scenes as ws


def _scene(boxes, pitch, roll=0.0, height=1.3):
    left, right, _, rig = ws.render(boxes, supersample=1, cam_height=height, pitch_deg=pitch, roll_deg=roll)
    return left, rig, sc.compute_disparity(left, right, num_disparities=64).disparity


def test_gravity_conventions_match_the_ground_plane():
    for pitch, roll in [(0.0, 0.0), (20.0, 0.0), (-30.0, 5.0), (35.0, -12.0)]:
        g = Gravity(ws.camera_up(pitch, roll), lines=8, length_px=500.0)
        assert g.pitch_deg == pytest.approx(pitch) and g.roll_deg == pytest.approx(roll)
    plane = GroundPlane.from_mounting(1.2, 15.0)
    g = Gravity(plane.up * 3.0, lines=8, length_px=500.0)                        # normalised when built
    assert g.pitch_deg == pytest.approx(plane.pitch_deg) and g.angle_deg(plane.up) == pytest.approx(0.0, abs=1e-6)
    assert g.to_dict() == {"pitch_deg": 15.0, "roll_deg": 0.0, "lines": 8}
    with pytest.raises(ValueError, match="`up`"):
        Gravity(np.zeros(3), lines=1, length_px=1.0)


@pytest.mark.parametrize("pitch, roll", [(0.0, 0.0), (10.0, 0.0), (10.0, 8.0), (20.0, -6.0), (-25.0, 0.0)])
def test_poles_give_the_camera_pitch_and_roll(pitch, roll):
    """Eight dark poles on a floor, rendered at a known pitch and roll (320x240, f = 300 px): the estimate is
    within 1 degree (measured: 0.15-0.35)."""
    left, rig, measured = _scene(ws.floor() + ws.poles(), pitch, roll)
    g = estimate_gravity(left, rig, measured=measured)
    assert g is not None and g.lines >= 6
    assert g.angle_deg(ws.camera_up(pitch, roll)) < 1.0
    assert g.pitch_deg == pytest.approx(pitch, abs=1.0) and g.roll_deg == pytest.approx(roll, abs=1.0)
    again = estimate_gravity(left, rig, measured=measured)                       # deterministic
    np.testing.assert_array_equal(g.up, again.up)


@pytest.mark.parametrize("front", [3.0, 2.5, 2.1])
def test_texture_alone_gives_no_estimate(front):
    """The rendered walk's noise texture makes short segments, a few of which meet somewhere by chance (without
    the a-contrario and length tests: 6-8 segments at a 'pitch' of 63-75 degrees): no estimate, not a guess."""
    box = ws.Box(-0.3, 0.3, 0.0, 0.8, front, front + 0.4, seed=5)
    left, rig, measured = _scene(ws.floor() + [box, ws.Box(1.8, 1.9, 0.0, 3.0, 0.0, 20.0, seed=7)], 10.0, 0.0, 1.2)
    assert estimate_gravity(left, rig, measured=measured) is None


def test_lines_where_nothing_was_measured_do_not_count():
    """The measured disparity says where the scene is: with nothing measured there is no line of it (a
    rectified image's border smears into streaks)."""
    left, rig, measured = _scene(ws.floor() + ws.poles(), 10.0)
    assert estimate_gravity(left, rig, measured=measured) is not None
    assert estimate_gravity(left, rig, measured=np.full_like(measured, np.nan)) is None


def test_bad_input_is_named():
    left, rig, measured = _scene(ws.floor() + ws.poles(), 10.0)
    with pytest.raises(GuideInputError, match="`image`.*320x240"):
        estimate_gravity(left[:100], rig)
    with pytest.raises(GuideInputError, match="`image`"):
        estimate_gravity(left.astype(np.float32), rig)
    with pytest.raises(GuideInputError, match="`measured`"):
        estimate_gravity(left, rig, measured=measured[:10])
    with pytest.raises(GuideInputError, match="`rig`"):
        estimate_gravity(left, "rig")
    assert estimate_gravity(left[..., 0].copy(), rig, measured=measured) is not None     # grey works too


@pytest.mark.parametrize("start, pitch, height", [(0.8, -25.0, 1.5), (1.0, -20.0, 1.5), (0.8, -25.0, 1.2)])
def test_stairs_up_are_not_the_ground(start, pitch, height):
    """Stairs going up, seen from their bottom by a camera looking up the flight (the OAK-D stairs frame): the
    steps make one plane along the nosings that a carried camera could stand on, and without the measured up it
    is taken for the ground (the premise); the balusters' vertical lines say the camera looks up, and that plane
    is 30 degrees from level: no ground."""
    left, rig, measured = _scene(ws.stairs_up(start), pitch, 0.0, height)
    points = frame_points(measured, rig, GuideParams(), left)
    fb = rig.focal_px * rig.baseline_m
    g = estimate_gravity(left, rig, measured=measured)
    assert g is not None and g.pitch_deg == pytest.approx(pitch, abs=1.5)
    for seed in range(3):
        slope = fit_ground(points, fb, rng=seed)
        assert slope is not None and g.angle_deg(slope.up) > 25.0                 # the flight's plane
        assert fit_ground(points, fb, rng=seed, gravity=g.up) is None


def test_gravity_must_be_a_direction():
    left, rig, measured = _scene(ws.floor() + ws.poles(), 10.0)
    points = frame_points(measured, rig, GuideParams(), left)
    for bad in (np.zeros(3), np.array([0.0, np.nan, 1.0]), np.ones(2)):
        with pytest.raises(ValueError, match="`gravity`"):
            fit_ground(points, 36.0, gravity=bad)


def test_a_level_floor_passes_the_measured_up():
    """The poles' up and the floor agree (rendered: the floor 1.3 m under a camera looking down 10 degrees,
    rolled 8): the ground is the same with and without it."""
    left, rig, measured = _scene(ws.floor() + ws.poles(), 10.0, 8.0)
    points = frame_points(measured, rig, GuideParams(), left)
    fb = rig.focal_px * rig.baseline_m
    g = estimate_gravity(left, rig, measured=measured)
    plain, level = fit_ground(points, fb, rng=0), fit_ground(points, fb, rng=0, gravity=g.up)
    assert plain is not None and level is not None
    assert level.height_m == pytest.approx(1.3, abs=0.05) and level.height_m == pytest.approx(plain.height_m)
    assert g.angle_deg(level.up) < 2.0


# ---------------------------------------------------------------------------------------------- real scenes
# corridor is not among them: its floor is a strip at 2-4 m under white walls that one frame's fit_ground finds for
# only some seeds (5 of seeds 0-7 before issue 35's neutral cost of a match outside the right image, 2 after; the
# guide's five-frame sequence 5/5 and 3/5, python -m benchmarks.guide_ground --seeds 8): one frame and one seed would
# test the seed. desk, the other scene whose floor comes and goes, gained (2/5 -> 5/5).
_FLOORS = ("bedroom_chair", "cycles", "donkey_toy", "living_room", "pov_controllers", "pov_hands", "toy")


def _oakd(shared_data, name):
    import calib
    from stereo_classic.io import read_image

    folder = shared_data / "oakd"
    rig = calib.load_rig(folder / "stereodemo_calibration.json")
    left, right = read_image(folder / f"{name}_left.png"), read_image(folder / f"{name}_right.png")
    return left, rig, sc.compute_disparity(left, right, num_disparities=64).disparity


@pytest.mark.parametrize("name", _FLOORS)
def test_real_vertical_lines_agree_with_the_floor(shared_data, name):
    """On the OAK-D scenes whose floor the guide fits (their overlays' corridor lines lie on it), the up of the
    vertical lines is within the level tolerance of the floor's normal, so the floor stays the ground (python -m
    benchmarks.guide_ground: 0.6-5.0 degrees, corridor 7.5, whose floor is seen in a strip at 2-4 m and fitted
    with a roll of 7.8 degrees where its door frames say 0.7; the guide's first frame draws with seed 1)."""
    left, rig, measured = _oakd(shared_data, name)
    g = estimate_gravity(left, rig, measured=measured)
    floor = fit_ground(frame_points(measured, rig, GuideParams(), left), rig.focal_px * rig.baseline_m, rng=1)
    assert g is not None and floor is not None
    assert g.angle_deg(floor.up) < GRAVITY_TOLERANCE_DEG
    assert abs(g.roll_deg) < 10.0 and -5.0 < g.pitch_deg < 40.0


def test_real_stairs_frame_looks_up_the_flight(shared_data):
    """The OAK-D stairs frame is seen from the bottom of the flight: its balusters and the door frame at the top
    converge upwards (a camera looking up about 28 degrees), and no plane in view is level."""
    left, rig, measured = _oakd(shared_data, "stairs")
    g = estimate_gravity(left, rig, measured=measured)
    assert g is not None and g.lines >= 10
    assert -35.0 < g.pitch_deg < -20.0 and abs(g.roll_deg) < 6.0
    points = frame_points(measured, rig, GuideParams(), left)
    fb = rig.focal_px * rig.baseline_m
    assert all(fit_ground(points, fb, rng=seed, gravity=g.up) is None for seed in range(4))
    assert math.isfinite(g.length_px)


def _road_up(scene):
    """The road's up from the frame's LiDAR ground truth: points of the lower 40 % of the image 1 m or more below
    the camera and nearer than 25 m, RANSAC (fixed seed, 5 cm band) then least squares on the inliers."""
    from calib.geometry import points_from_pixels

    gt = scene.gt_disparity
    h = gt.shape[0]
    v, u = np.nonzero(np.isfinite(gt) & (np.arange(h)[:, None] > 0.6 * h))
    pts = points_from_pixels(u.astype(np.float64), v.astype(np.float64), gt[v, u], scene.rig)
    pts = pts[(pts[:, 2] < 25.0) & (pts[:, 1] > 1.0)]
    gen, best, best_n = np.random.default_rng(0), None, -1
    for _ in range(300):
        a, b, c = pts[gen.integers(0, len(pts), 3)]
        normal = np.cross(b - a, c - a)
        if np.linalg.norm(normal) < 1e-9:
            continue
        normal /= np.linalg.norm(normal)
        count = int((np.abs((pts - a) @ normal) < 0.05).sum())
        if count > best_n:
            best, best_n = (normal, a), count
    normal, a = best
    inl = pts[np.abs((pts - a) @ normal) < 0.05]
    up = np.linalg.svd(inl - inl.mean(axis=0), full_matrices=False)[2][-1]
    return up if up[1] < 0 else -up


def test_real_driving_frames_vertical_lines_agree_with_the_road(shared_data):
    """The ten DrivingStereo frames: the up of the vertical lines (poles, buildings, a car camera mounted level:
    pitch -0.1 to 2.8 degrees) is within 3 degrees of the road's plane fitted to the LiDAR ground truth (measured
    0.4-2.2; 9 of the 10 frames give an estimate; the road's camber and slope are a degree or so), a fifth of the
    15 degrees the guide allows a level ground."""
    from stereo_classic.datasets.drivingstereo import iter_drivingstereo

    angles = []
    for scene in iter_drivingstereo(shared_data / "drivingstereo"):
        measured = sc.compute_disparity(scene.left, scene.right, num_disparities=96).disparity
        g = estimate_gravity(scene.left, scene.rig, measured=measured)
        if g is not None:
            angles.append(g.angle_deg(_road_up(scene)))
    assert len(angles) >= 8 and max(angles) < 3.0
