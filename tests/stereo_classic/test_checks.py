"""The frame checks (issue #15 items 1 and 2): disparities piled at the end of the range give a warning with the
range that fits and ``beyond_range`` objects instead of distances; a swapped or mismatched pair gives a warning and
``pair_mismatch`` objects; no false alarm on any unswapped shared scene."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stereo_classic.checks import (
    PAIR_CLEAR,
    SATURATION_WARN,
    FrameChecker,
    FrameWarning,
    range_saturation,
)
from stereo_classic.matching import DisparityMap, SGMParams
from stereo_classic.pipeline import Localizer
from tests.helpers.detectors import FixedBoxes
from tests.helpers.scenes import disparity_of, make_rig, planted_scene

BOX = (100, 60, 200, 140)


@pytest.fixture(scope="module")
def near_scene():
    """A textured box 1 m in front of a wall at 8 m: 84 px of disparity (focal 700 px, baseline 0.12 m)."""
    rig = make_rig(320, 200)
    left, right, _, rig = planted_scene(width=320, height=200, z_box=1.0, z_wall=8.0, box=BOX, rig=rig)
    assert disparity_of(1.0, rig) == pytest.approx(84.0)
    return left, right, rig


def test_range_saturation_counts_known_pixels_within_one_px_of_the_end():
    d = np.array([[1.0, 63.0, 62.0, 61.9, np.nan]], np.float32)
    assert range_saturation(d, 63) == pytest.approx(0.5)
    assert range_saturation(np.full((2, 2), np.nan), 63) == 0.0


def test_range_warning_reads_the_measured_pixels_only(near_scene):
    """The ``disparity`` command's range warning: pixels at the end of the range that were filled are guesses
    and do not saturate; measured, the same values do."""
    left, right, _ = near_scene
    d = np.full((200, 320), 10.0, np.float32)
    d[60:140, 100:200] = 47.0                                        # 12.5 % of the pixels at the end of 0..47
    checker = FrameChecker(SGMParams(num_disparities=48))
    try:
        measured = DisparityMap(d, None, SGMParams(num_disparities=48))
        filled = DisparityMap(d, None, SGMParams(num_disparities=48), filled=d >= 47.0)
        assert checker.range_warning(left, right, measured).code == "range_saturated"
        assert checker.range_warning(left, right, filled) is None
    finally:
        checker.close()


def test_object_beyond_the_range_is_marked_and_the_frame_says_which_range_fits(near_scene):
    left, right, rig = near_scene
    # no hole filling: the box's pixels that match nothing are what makes it suspect here (no pile-up)
    with Localizer(rig, FixedBoxes([BOX]), {"num_disparities": 48, "fill_holes": False}) as loc:
        r = loc(left, right)
    assert r.objects.status == ("beyond_range",) and math.isnan(r.objects.distance_m[0])
    assert [w.code for w in r.warnings] == ["range_saturated"]
    msg = r.warnings[0].message
    assert "end of the disparity range (47 px = 1.79 m)" in msg and "beyond_range" in msg
    assert "--num-disparities 96" in msg  # about 84 px are needed
    assert r.objects.to_json()[0]["distance_m"] is None


def test_a_frames_checks_share_its_half_size_images(near_scene, monkeypatch):
    """The pair check and the range check resize each image of the frame once, and give what they give with images
    of their own (the same objects, statuses and warning)."""
    import stereo_classic.checks as checks

    left, right, rig = near_scene
    resized = []
    real_half = checks._half
    monkeypatch.setattr(checks, "_half", lambda image: resized.append(image.shape) or real_half(image))
    with Localizer(rig, FixedBoxes([BOX]), {"num_disparities": 48, "fill_holes": False}) as loc:
        r = loc(left, right)
    assert len(resized) == 2 and r.objects.status == ("beyond_range",)  # both checks looked (the range one too)
    checker = FrameChecker(SGMParams(num_disparities=48, fill_holes=False))
    try:
        resized.clear()
        alone = checker.check_range(left, right, r.disparity, r.objects, rig, loc.fusion, loc.seed)
        assert len(resized) == 2  # its own two
        assert checker.check_pair(left, right, r.disparity) is None and len(resized) == 2  # cleared by the match
        assert checker.check_pair(left, right, _blank(left)) is None and len(resized) == 4  # looked: its own two
    finally:
        checker.close()
    assert alone[0].status == r.objects.status and [alone[1].code] == [w.code for w in r.warnings]
    assert alone[1].message == r.warnings[0].message


def test_the_range_that_fits_measures_it_without_a_warning(near_scene):
    left, right, rig = near_scene
    with Localizer(rig, FixedBoxes([BOX]), {"num_disparities": 96}) as loc:
        r = loc(left, right)
    assert r.objects.status == ("ok",) and r.warnings == ()
    assert r.objects.distance_m[0] == pytest.approx(1.0, rel=0.02)


def test_checks_can_be_turned_off(near_scene):
    left, right, rig = near_scene
    with Localizer(rig, FixedBoxes([BOX]), {"num_disparities": 48}, checks=False) as loc:
        r = loc(left, right)
    assert r.objects.status == ("ok",) and r.warnings == () and "checks" in r.timings_ms


def test_swapped_planted_pair_reports_no_distance(near_scene):
    left, right, rig = near_scene
    with Localizer(rig, FixedBoxes([BOX, (10, 10, 60, 60)]), {"num_disparities": 96}) as loc:
        r = loc(right, left)
    assert r.objects.status == ("pair_mismatch", "pair_mismatch")
    assert np.isnan(r.objects.distance_m).all() and [w.code for w in r.warnings] == ["swapped_pair"]
    assert "swapped" in r.warnings[0].message


def test_a_right_image_from_another_place_is_a_mismatch(near_scene):
    left, right, _ = near_scene
    other = np.roll(right, 15, axis=0)  # rows do not correspond any more
    checker = FrameChecker(SGMParams(num_disparities=96))
    warning = checker.check_pair(left, other, _blank(left))
    assert isinstance(warning, FrameWarning) and warning.code == "pair_mismatch"


def _blank(image) -> DisparityMap:
    h, w = image.shape[:2]
    return DisparityMap(np.zeros((h, w), np.float32), None, SGMParams())


def _range(scene) -> int:
    return int(16 * math.ceil((scene.max_disparity + 1) / 16)) if scene.max_disparity else 128


def test_no_false_alarm_on_any_shared_scene_and_every_swap_found(shared_data):
    """Every scene of ../shared/data at the range `run` picks: the pair check stays quiet as given and calls the
    swapped pair swapped (the KITTI pair, Middlebury, DrivingStereo and OAK-D scenes)."""
    from stereo_classic.datasets import iter_scenes

    names, quiet, swapped = [], [], []
    for scene in iter_scenes(shared_data):
        params = SGMParams(num_disparities=_range(scene))
        names.append(scene.name)
        quiet.append(FrameChecker(params).check_pair(scene.left, scene.right, _blank(scene.left)))
        warning = FrameChecker(params).check_pair(scene.right, scene.left, _blank(scene.left))
        swapped.append(None if warning is None else warning.code)
    assert len(names) >= 25 and "kitti_object_pair" in names
    assert [n for n, w in zip(names, quiet) if w is not None] == []
    assert [n for n, code in zip(names, swapped) if code != "swapped_pair"] == []


def test_oakd_hands_at_the_dataset_range_warn(shared_data):
    """The OAK-D dataset picks 64 disparities from its calibration's near limit; the hands are at about 75 px."""
    from stereo_classic.datasets import load_scene

    scene = load_scene(shared_data / "oakd" / "pov_hands")
    assert _range(scene) == 64
    with Localizer(scene.rig, None, {"num_disparities": 64}) as loc:
        r = loc(scene.left, scene.right)
    share = range_saturation(r.disparity.disparity, 63)
    assert share >= SATURATION_WARN
    assert [w.code for w in r.warnings] == ["range_saturated"]
    assert "--num-disparities 96" in r.warnings[0].message or "--num-disparities 112" in r.warnings[0].message


def test_kitti_near_car_beyond_64_disparities(shared_data):
    """At 64 disparities the near car (about 3.4 m, 110 px) used to read 7.06 m, ok."""
    from stereo_classic.datasets import load_scene

    scene = load_scene(shared_data / "kitti_object_pair")
    near_car = (812.76, 184.44, 1241.0, 374.0)  # label_2.txt, the car at 4.3 m (bottom centre)
    far_car = (470.09, 178.30, 539.83, 233.30)  # the car at 22.9 m
    with Localizer(scene.rig, FixedBoxes([near_car, far_car]), {"num_disparities": 64}) as loc:
        r = loc(scene.left, scene.right)
    assert r.objects.status == ("beyond_range", "ok")
    assert r.objects.distance_m[1] == pytest.approx(22.0, rel=0.05)
    assert [w.code for w in r.warnings] == ["range_saturated"]
    assert "--num-disparities 128" in r.warnings[0].message or "at least 128" in r.warnings[0].message


def test_the_same_image_twice_is_not_a_pair(near_scene):
    left, _, rig = near_scene
    with Localizer(rig, FixedBoxes([BOX]), {"num_disparities": 96}) as loc:
        r = loc(left, left.copy())
    assert r.objects.status == ("pair_mismatch",)
    assert [w.code for w in r.warnings] == ["pair_mismatch"] and "same image" in r.warnings[0].message


def test_same_image_is_the_whole_comparison():
    from stereo_classic.checks import _same_image

    img = np.random.default_rng(0).integers(0, 256, (40, 50, 3), dtype=np.uint8)
    assert _same_image(img, img.copy())
    for y, x in ((0, 0), (1, 1), (39, 49)):  # on the sampled grid, off it, at the far corner
        other = img.copy()
        other[y, x, 2] ^= 1
        assert not _same_image(img, other)
    assert not _same_image(img, img[:, :40])


@pytest.mark.parametrize("order", ["as given", "swapped"])
def test_the_look_is_the_same_for_any_thread_count(near_scene, order):
    """The frame's one half-size look (both signs of disparity, twice the reach) and so the pair check's answer do
    not depend on the thread count; the given order's pixels lie at positive disparities, the swapped ones' at
    negative ones."""
    left, right, _ = near_scene
    if order == "swapped":
        left, right = right, left
    checkers = [FrameChecker(SGMParams(num_disparities=96, threads=t)) for t in (1, 2, 3)]
    try:
        assert checkers[0].look_range() == (-48, 144)  # -48 .. 95 at half size: the mirror of 0..95, twice 0..47
        looks = [c._look(c.halves(left, right)) for c in checkers]
        for look in looks[1:]:
            np.testing.assert_array_equal(look.disparity, looks[0].disparity)
        given, other = checkers[0].order_shares(looks[0])
        assert (given > 0.5 and other < 0.05) if order == "as given" else (other > 0.5 and given < 0.05)
        blank = _blank(left)
        answers = {c.check_pair(left, right, blank) for c in checkers}
        assert len(answers) == 1 and (answers.pop() is None) == (order == "as given")
    finally:
        for c in checkers:
            c.close()


def test_the_look_has_its_own_settings_whatever_the_callers(near_scene):
    """The look's settings are fixed (the checks' shares and thresholds were measured with them): a caller's
    ``median_filter`` or ``fill_holes`` changes the frame's match, not the look."""
    left, right, _ = near_scene
    looks = []
    for extra in ({}, {"median_filter": True, "fill_holes": False, "speckle_size": 100}):
        checker = FrameChecker(SGMParams(num_disparities=96, **extra))
        try:
            looks.append(checker._look(checker.halves(left, right)))
        finally:
            checker.close()
    assert not looks[1].params.median_filter and not looks[1].params.fill_holes
    np.testing.assert_array_equal(looks[0].disparity, looks[1].disparity)


def test_a_range_symmetric_about_zero_cannot_tell_the_order(near_scene):
    """With disparities from -48 to 47 both orders have the same ones: the pair check says nothing rather than
    guess (the range check still looks)."""
    left, right, _ = near_scene
    checker = FrameChecker(SGMParams(min_disparity=-48, num_disparities=96))
    try:
        assert checker.check_pair(left, right, _blank(left)) is None
        assert checker.check_pair(right, left, _blank(left)) is None
    finally:
        checker.close()


def test_a_frame_is_looked_at_once(near_scene, monkeypatch):
    """The pair check and the range check of one frame read the same half-size look: one match a frame."""
    left, right, rig = near_scene
    with Localizer(rig, FixedBoxes([BOX]), {"num_disparities": 48, "fill_holes": False}) as loc:
        loc(left, right)  # compiled, allocated
        calls = []
        for matcher in (loc.checker._matcher, loc.checker._range_matcher):  # both looks, whichever was made
            if matcher is not None:
                monkeypatch.setattr(matcher, "compute",
                                    lambda *a, _real=matcher.compute, **k: calls.append(1) or _real(*a, **k))
        r = loc(left, right)
    assert r.objects.status == ("beyond_range",) and len(calls) == 1  # both checks looked, one match


def test_the_range_check_reads_the_given_orders_side_of_the_look():
    """The range check reads the look as the given order's map: its negative side (the exchanged order's) is
    unknown, and so is the left border that reaches less than ``border_reach`` of the given order's range (as the
    look over that range alone would have it; the look's own border rule counts its negative side too)."""
    checker = FrameChecker(SGMParams(num_disparities=48))
    low, num = checker.look_range()
    assert (low, num) == (-32, 80)
    d = np.full((10, 40), 30.0, np.float32)
    d[:, 30:] = -5.0                                             # matched as if exchanged
    wide = checker._reach(DisparityMap(d, None, SGMParams(min_disparity=low, num_disparities=num)), 80, 20)
    assert wide.shape == (20, 80)
    known = np.isfinite(wide[0])
    assert not known[:2 * 23].any() and known[2 * 23:2 * 30].all() and not known[2 * 30:].any()
    np.testing.assert_array_equal(wide[0, 2 * 23:2 * 30], 60.0)   # full-size pixels: twice the half-size ones


def test_the_frames_own_match_clears_real_pairs_only(shared_data):
    """The pair check reads the frame's own match first: on every shared scene the answer is what the look alone
    gives (quiet as given, swapped when swapped), no swapped pair and no pair of unrelated images is cleared by the
    match, and the KITTI pair is (its frames skip the look)."""
    from stereo_classic.datasets import iter_scenes
    from stereo_classic.matching import StereoMatcher

    matchers: dict[int, StereoMatcher] = {}

    def check(left, right, num):
        matcher = matchers.setdefault(num, StereoMatcher(SGMParams(num_disparities=num)))
        checker = FrameChecker(matcher.params)
        try:
            dmap = matcher.compute(left, right)
            return checker.given_share(dmap), checker.check_pair(left, right, dmap)
        finally:
            checker.close()

    scenes = list(iter_scenes(shared_data))
    loud, cleared_swaps, missed, cleared = [], [], [], []
    for scene in scenes:
        share, warning = check(scene.left, scene.right, _range(scene))
        if warning is not None:
            loud.append(scene.name)
        if share >= PAIR_CLEAR:
            cleared.append(scene.name)
        share, warning = check(scene.right, scene.left, _range(scene))
        if share >= PAIR_CLEAR:
            cleared_swaps.append(scene.name)
        if warning is None or warning.code != "swapped_pair":
            missed.append(scene.name)
    assert loud == [] and cleared_swaps == [] and missed == []
    assert "kitti_object_pair" in cleared and len(cleared) >= 20
    oakd = [s for s in scenes if s.left.shape[:2] == (480, 640)]
    assert len(oakd) == 12
    for a, b in zip(oakd[::2], oakd[1::2]):  # a left image with another scene's right one
        share, warning = check(a.left, b.right, 64)
        assert share < PAIR_CLEAR and warning is not None and warning.code == "pair_mismatch", (a.name, b.name)
    for s in oakd:  # rows that do not correspond: never cleared, the look decides (as before)
        share, _ = check(s.left, np.roll(s.right, 15, axis=0), 64)
        assert share < PAIR_CLEAR, s.name
    for matcher in matchers.values():
        matcher.release()


@pytest.mark.parametrize("options", [{"lr_check": None}, {"lr_check": 2.0}, {"lr_mode": "opencv"}])
def test_a_match_without_the_full_1px_check_clears_nothing(near_scene, options):
    """Pixels not checked left-right within 1 px in full need not be consistent: the look decides."""
    from stereo_classic.matching import StereoMatcher

    left, right, _ = near_scene
    matcher = StereoMatcher(SGMParams(num_disparities=96, **options))
    checker = FrameChecker(matcher.params)
    try:
        dmap = matcher.compute(left, right)
        assert checker.given_share(dmap) is None
        halves = checker.halves(left, right)
        assert checker.check_pair(left, right, dmap, halves) is None and halves.looked and not halves.cleared
    finally:
        checker.close()
        matcher.release()
