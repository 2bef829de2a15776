"""Ground plane: mounting geometry, RANSAC fit on known planes, stability over frames, given height/pitch."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_classic.guide import (
    GroundPlane,
    GroundTracker,
    GuideParams,
    PointSample,
    fit_ground,
)


def _floor_sample(height=1.3, pitch=12.0, n=3000, noise=0.01, clutter=0, seed=0):
    """Camera-frame points of a floor seen by a camera ``height`` m up, looking down ``pitch`` degrees."""
    rng = np.random.default_rng(seed)
    plane = GroundPlane.from_mounting(height, pitch)
    lat = rng.uniform(-2, 2, n)
    fwd = rng.uniform(1.0, 4.0, n)
    pts = plane.to_camera(lat, fwd, rng.normal(0, noise, n))
    if clutter:                                   # a table top 0.7 m up and a wall
        pts = np.vstack([pts, plane.to_camera(rng.uniform(-0.5, 0.5, clutter), rng.uniform(1.5, 2.5, clutter), 0.7),
                         plane.to_camera(np.full(clutter, 1.0), rng.uniform(1, 4, clutter),
                                         rng.uniform(0, 2, clutter))])
    f = 300.0
    uv = np.column_stack([f * pts[:, 0] / pts[:, 2] + 160, f * pts[:, 1] / pts[:, 2] + 120])
    return PointSample(uv=uv, xyz=pts, stride=2, focal_px=f), plane


def test_mounting_geometry():
    plane = GroundPlane.from_mounting(1.5, 20.0)
    assert plane.pitch_deg == pytest.approx(20.0) and plane.roll_deg == pytest.approx(0.0, abs=1e-9)
    ground = plane.to_ground(plane.to_camera(np.array([0.5, -1.0]), np.array([2.0, 3.0]), np.array([0.0, 1.0])))
    np.testing.assert_allclose(ground, [[0.5, 2.0, 0.0], [-1.0, 3.0, 1.0]], atol=1e-12)
    assert plane.to_dict() == {"height_m": 1.5, "pitch_deg": 20.0, "roll_deg": 0.0, "source": "given"}


@pytest.mark.parametrize("height, pitch, clutter", [(1.3, 12.0, 0), (0.8, 30.0, 0), (1.6, 5.0, 400), (1.3, 12.0, 800)])
def test_fit_recovers_height_and_pitch(height, pitch, clutter):
    sample, _ = _floor_sample(height, pitch, clutter=clutter)
    fit = fit_ground(sample, 36.0)
    assert fit is not None and fit.source == "fitted"
    assert fit.height_m == pytest.approx(height, abs=0.03)
    assert fit.pitch_deg == pytest.approx(pitch, abs=1.0)


def test_no_ground_is_none_not_a_guess():
    rng = np.random.default_rng(1)
    pts = np.column_stack([rng.uniform(-1, 1, 500), rng.uniform(-1, 1, 500), np.full(500, 3.0)])  # a wall only
    sample = PointSample(uv=np.column_stack([pts[:, 0] * 100 + 160, pts[:, 1] * 100 + 120]), xyz=pts, stride=2,
                         focal_px=300.0)
    assert fit_ground(sample, 36.0) is None
    tracker = GroundTracker(GuideParams())
    assert tracker.update(sample, 36.0) is None


def test_tracker_is_stable_and_keeps_the_last_plane():
    tracker = GroundTracker(GuideParams())
    heights = []
    for i in range(8):
        sample, _ = _floor_sample(1.3, 12.0, noise=0.03, seed=i)
        heights.append(tracker.update(sample, 36.0).height_m)
    assert np.ptp(heights) < 0.03 and abs(heights[-1] - 1.3) < 0.03
    empty = PointSample(uv=np.zeros((0, 2)), xyz=np.zeros((0, 3)), stride=2, focal_px=300.0)
    kept = tracker.update(empty, 36.0)
    assert kept.source == "kept" and kept.height_m == pytest.approx(heights[-1])


def test_given_height_and_pitch_replace_the_fit():
    sample, _ = _floor_sample(1.3, 12.0)
    both = GroundTracker(GuideParams(camera_height=1.0, camera_pitch=5.0)).update(sample, 36.0)
    assert (both.source, both.height_m, round(both.pitch_deg, 6)) == ("given", 1.0, 5.0)
    only_h = GroundTracker(GuideParams(camera_height=1.1)).update(sample, 36.0)
    assert only_h.height_m == 1.1 and only_h.pitch_deg == pytest.approx(12.0, abs=1.0)


@pytest.mark.parametrize("landing, pitch, expected_level", [(1.0, 40.0, 2), (1.5, 30.0, 0)])
def test_given_pitch_fits_the_height_along_it(landing, pitch, expected_level):
    """Stairs down seen from their top (camera 1.5 m up): the free fit takes a plane along the nosings for a level
    floor about 0.8 m down (the premise); with the pitch given, the ground is a level of the stairs, the same
    for every seed (every offset is tried, nothing is drawn): the landing 1.5 m down where it holds the most
    points, else the lowest large tread (the rule that takes the floor under a table: the landing then stands
    above it, an obstacle at the feet)."""
    from stereo_classic.guide.ground import sample_points
    from tests.helpers import walk_scenes as ws

    left, _, depth, rig = ws.render(ws.stairs_down(landing), supersample=1, cam_height=1.5, pitch_deg=pitch)
    fb = rig.focal_px * rig.baseline_m
    sample = sample_points((fb / depth).astype(np.float32), rig, stride=2, image=left)
    free = fit_ground(sample, fb)
    assert free is None or abs(free.height_m - 1.5) > 0.3 or abs(free.pitch_deg - pitch) > 5.0
    up = GroundPlane.from_mounting(1.0, pitch).up
    fits = [fit_ground(sample, fb, up=up, rng=seed) for seed in range(3)]
    assert all(f is not None and f.height_m == fits[0].height_m for f in fits)
    level = (fits[0].height_m - 1.5) / 0.17                                 # treads 0.17 m apart under the landing
    assert abs(level - round(level)) * 0.17 < 0.03 and fits[0].pitch_deg == pytest.approx(pitch, abs=1e-6)
    assert round(level) == expected_level
    tracked = GroundTracker(GuideParams(camera_pitch=pitch)).update(sample, fb)
    assert tracked.height_m == pytest.approx(fits[0].height_m, abs=0.03) and tracked.pitch_deg == pytest.approx(pitch)


def test_textureless_samples_do_not_make_the_ground():
    """A level 'floor' 0.5 m under the camera from a white wall's propagated depths loses to the textured floor."""
    sample, _ = _floor_sample(1.3, 12.0, n=1500)
    rng = np.random.default_rng(3)
    fake = GroundPlane.from_mounting(0.5, 0.0).to_camera(rng.uniform(-1, 1, 4000), rng.uniform(1, 3.5, 4000))
    f = 300.0
    fake_uv = np.column_stack([f * fake[:, 0] / fake[:, 2] + 160, f * fake[:, 1] / fake[:, 2] + 120])
    textured = np.concatenate([np.ones(len(sample.xyz), bool), np.zeros(len(fake), bool)])
    mixed = PointSample(np.vstack([sample.uv, fake_uv]), np.vstack([sample.xyz, fake]), 2, f, textured)
    fit = fit_ground(mixed, 36.0)
    assert fit is not None and fit.height_m == pytest.approx(1.3, abs=0.03)


def test_sample_points_marks_texture():
    from stereo_classic.guide.ground import sample_points
    from tests.helpers.scenes import make_rig

    rig = make_rig(40, 30)
    image = np.full((30, 40), 128, np.uint8)
    image[:, 20:] = np.random.default_rng(0).integers(0, 255, (30, 20))
    sample = sample_points(np.full((30, 40), 8.0, np.float32), rig, stride=2, image=image)
    assert sample.textured.dtype == bool and sample.textured.shape == (len(sample.xyz),)
    assert not sample.textured[sample.uv[:, 0] < 15].any() and sample.textured[sample.uv[:, 0] > 24].all()
    assert sample_points(np.full((30, 40), 8.0, np.float32), rig).textured is None


def _rendered(boxes, pitch):
    """Textured samples of a rendered frame (tests/helpers/walk_scenes.py, camera 1.2 m up), from its exact
    depth: the geometry, not the matcher, is what these tests are about."""
    from stereo_classic.guide.ground import sample_points
    from tests.helpers import walk_scenes as ws

    left, _, depth, rig = ws.render(ws.floor() + boxes, supersample=1, cam_height=1.2, pitch_deg=pitch)
    disparity = (rig.focal_px * rig.baseline_m / depth).astype(np.float32)
    return sample_points(disparity, rig, stride=2, image=left), rig.focal_px * rig.baseline_m


@pytest.mark.parametrize("top, x0, x1, far, pitch", [
    (0.6, -1.0, 1.0, 1.4, 15.0),      # a low table filling the near view, the floor beside and beyond it
    (0.45, -1.6, 0.4, 1.8, 20.0),     # a bed or a landing, wider and deeper, seen steeper
])
def test_floor_below_the_largest_plane_is_the_ground(top, x0, x1, far, pitch):
    """The naive largest plane is a table top (or a bed, a landing); the floor is lower and must be the ground."""
    from tests.helpers import walk_scenes as ws

    sample, fb = _rendered([ws.Box(x0, x1, top - 0.04, top, 0.2, far, seed=9)], pitch)
    floor, table = GroundPlane.from_mounting(1.2, pitch), GroundPlane.from_mounting(1.2 - top, pitch)
    pts, uv = sample.xyz[sample.textured], sample.uv[sample.textured]
    pts = pts[(uv[:, 1] > np.median(uv[:, 1])) & (pts[:, 2] < 4.0)]       # what fit_ground looks at
    on_table, on_floor = (np.abs(table.heights(pts)) < 0.02).sum(), (np.abs(floor.heights(pts)) < 0.02).sum()
    assert on_table > 2 * on_floor > 0                                    # the premise: the table is the largest
    for seed in range(3):
        fit = fit_ground(sample, fb, rng=seed)
        assert fit is not None
        assert fit.height_m == pytest.approx(1.2, abs=0.03) and fit.pitch_deg == pytest.approx(pitch, abs=1.0)


def test_a_desk_alone_is_not_the_ground():
    """Only a desk top in view (no floor within the lower half of the image and 4 m): too narrow for the walking
    corridor, so no ground rather than a desk 0.45 m under the camera."""
    from tests.helpers import walk_scenes as ws

    sample, fb = _rendered([ws.Box(-1.0, 1.0, 0.71, 0.75, 0.2, 1.5, seed=9)], 20.0)
    desk = GroundPlane.from_mounting(0.45, 20.0)
    assert (np.abs(desk.heights(sample.xyz[sample.textured])) < 0.02).mean() > 0.3    # the desk is in view
    assert fit_ground(sample, fb) is None
    assert fit_ground(sample, fb, min_width=0.5).height_m == pytest.approx(0.45, abs=0.03)   # it is a plane
    assert GroundTracker(GuideParams()).update(sample, fb) is None                  # the guide: corridor 1.0 m
    narrow = GroundTracker(GuideParams(corridor_width=0.5)).update(sample, fb)       # a 0.5 m corridor fits on it
    assert narrow.height_m == pytest.approx(0.45, abs=0.03)


def test_estimated_height_must_be_plausible():
    """A floor 2.6 m under the camera (a balcony, or a plane through far clutter) is not estimated as the
    ground (ESTIMATED_HEIGHT_RANGE); a given `camera_height` up to 5 m is still taken."""
    sample, _ = _floor_sample(2.6, 25.0)
    assert fit_ground(sample, 36.0) is None
    assert fit_ground(sample, 36.0, height_range=(0.3, 3.0)).height_m == pytest.approx(2.6, abs=0.03)
    assert GroundTracker(GuideParams(camera_height=2.6)).update(sample, 36.0) is None
    given = GroundTracker(GuideParams(camera_height=2.6, camera_pitch=25.0)).update(sample, 36.0)
    assert given.height_m == 2.6


@pytest.mark.parametrize("h, w, stride, channels", [(30, 40, 2, 1), (97, 131, 5, 3), (24, 24, 4, 1)])
def test_texture_grid_equals_the_reference(h, w, stride, channels):
    from stereo_classic.guide.ground import _texture, _texture_grid

    rng = np.random.default_rng(h)
    image = rng.integers(0, 256, (h, w) if channels == 1 else (h, w, 3)).astype(np.uint8)
    off = stride // 2
    vs, us = np.mgrid[off:h:stride, off:w:stride]
    grid = _texture_grid(image, off, stride, vs.shape)
    np.testing.assert_array_equal(grid.ravel(), _texture(image, us.ravel().astype(float), vs.ravel().astype(float)))


def test_consensus_is_the_majority_plane_or_none():
    from stereo_classic.guide.ground import consensus

    a, b, c = (GroundPlane.from_mounting(h, p, "fitted") for h, p in ((1.30, 12.0), (1.34, 13.0), (1.32, 12.5)))
    table = GroundPlane.from_mounting(0.6, 12.0, "fitted")
    assert consensus([a, b, table], 5) is None                  # 2 of 5 searches agree: no majority
    assert consensus([a, b, c, table], 7) is None               # 3 of 7: four searches found none
    got = consensus([a, table, b, c], 5)                        # 3 of 5 are a majority, whatever the order
    assert got.height_m == pytest.approx(1.32) and got.pitch_deg == pytest.approx(12.5, abs=0.01)
    assert consensus([], 5) is None and consensus([table], 1).height_m == pytest.approx(0.6)


def test_restarts_must_be_a_positive_integer():
    sample, _ = _floor_sample()
    for bad in (0, -1, 2.5, True, "5"):
        with pytest.raises(ValueError, match=r"`restarts` must be a positive integer.*got"):
            fit_ground(sample, 36.0, restarts=bad)
    one = fit_ground(sample, 36.0, restarts=1)                  # a floor seen well: one search is as good
    assert one.height_m == pytest.approx(fit_ground(sample, 36.0).height_m, abs=0.01)


def test_real_corridor_ground_does_not_depend_on_the_draw(shared_data):
    """The OAK-D corridor shows a strip of floor beside a stairwell, and one search's ground depends on its
    draw (seeds 0-7: 0.5 to 1.72 m); the consensus of five searches is the same plane, or unknown, for every
    seed (python -m benchmarks.guide_ground --seeds 8: known for 2 of the 8 seeds since issue 35's neutral cost of a
    match outside the right image, 5 before)."""
    import calib
    from stereo_classic.guide.core import frame_points
    from stereo_classic.guide.ground import agree
    from stereo_classic.io import read_image
    from stereo_classic.pipeline import Localizer

    folder = shared_data / "oakd"
    rig = calib.load_rig(folder / "stereodemo_calibration.json")
    with Localizer(rig, None, {"num_disparities": 64}) as loc:
        result = loc(read_image(folder / "corridor_left.png"), read_image(folder / "corridor_right.png"))
    points = frame_points(result.disparity.disparity, rig, GuideParams(), result.left)
    fb = rig.focal_px * rig.baseline_m
    single = [fit_ground(points, fb, rng=seed, restarts=1) for seed in range(8)]
    single = [f for f in single if f is not None]
    assert not all(agree(f, g) for f in single for g in single)       # the premise: one search is not enough
    fits = [fit_ground(points, fb, rng=seed) for seed in range(8)]
    known = [f for f in fits if f is not None]
    assert len(known) >= 2 and all(agree(f, g) for f in known for g in known)
    assert all(1.2 < f.height_m < 1.6 for f in known)               # held at chest height, not a railing's plane


def test_tracker_drops_a_plane_the_measured_up_contradicts():
    """A plane adopted before the image showed which way is up (no vertical lines in view) is kept while the
    measured up contradicts it for fewer than 3 frames in a row, then dropped: the ground is unknown, not a
    30-degree slope. A level plane found meanwhile replaces it at once."""
    tracker = GroundTracker(GuideParams())
    sample, _ = _floor_sample(1.3, 12.0)
    assert tracker.update(sample, 36.0).source == "fitted"
    up = GroundPlane.from_mounting(1.0, 42.0).up                      # the lines say: 30 degrees from this plane
    assert tracker.update(sample, 36.0, gravity=up).source == "kept"
    assert tracker.update(sample, 36.0, gravity=up).source == "kept"
    assert tracker.update(sample, 36.0, gravity=up) is None
    assert tracker.update(sample, 36.0) is not None                   # without a measured up it is taken again

    tracker = GroundTracker(GuideParams())
    tracker.update(sample, 36.0)
    level, _ = _floor_sample(1.1, 30.0, seed=3)                       # a floor 18 degrees from the plane held
    plane = tracker.update(level, 36.0, gravity=GroundPlane.from_mounting(1.0, 30.0).up)   # and level
    assert tracker.switched and plane.pitch_deg == pytest.approx(30.0, abs=1.0)
    assert plane.height_m == pytest.approx(1.1, abs=0.03)


def test_a_given_pitch_wins_over_the_measured_up():
    sample, _ = _floor_sample(1.3, 12.0)
    up = GroundPlane.from_mounting(1.0, 42.0).up
    plane = GroundTracker(GuideParams(camera_pitch=12.0)).update(sample, 36.0, gravity=up)
    assert plane is not None and plane.pitch_deg == pytest.approx(12.0)
    assert plane.height_m == pytest.approx(1.3, abs=0.03)
    assert fit_ground(sample, 36.0, gravity=up) is None                # the free fit honours it
