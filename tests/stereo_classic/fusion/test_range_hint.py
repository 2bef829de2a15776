"""Tests for stereo_classic.fusion.range_hint: a bare localize() call says when a box's disparities pile up at the
end of the searched range (issue 34, item 4), and stays silent otherwise, on a plain array, or when told to."""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

from stereo_classic import checks
from stereo_classic.fusion import RangeWarning, localize
from stereo_classic.fusion.range_hint import PILE_SHARE, piled_boxes
from tests.helpers.scenes import make_rig


def _dmap(value: float, top: int = 63, piled_rows: int = 0) -> SimpleNamespace:
    disp = np.full((30, 40), value, np.float32)
    disp[5:5 + piled_rows, :] = top  # rows of the box at the end of the range
    return SimpleNamespace(disparity=disp, measured_disparity=disp, params=SimpleNamespace(max_disparity=top))


BOX = np.array([[10, 5, 30, 25]], np.float32)


def test_the_share_is_the_frame_checks_share():
    assert PILE_SHARE == checks.BOX_SATURATION


def test_a_box_piled_at_the_end_of_the_range_warns_naming_the_object_and_the_way_out():
    rig = make_rig(40, 30, focal_px=500.0, baseline_m=0.1)
    with pytest.warns(RangeWarning, match=r"object at .* m: .*end of the searched range \(63 px\).*Localizer"):
        objs = localize(BOX, _dmap(62.5), rig, box_shrink=0.0)
    assert objs.status == ("ok",)  # the number stays; the caller was told


@pytest.mark.parametrize("case", ["far from the end", "plain array", "told not to"])
def test_silent_where_nothing_piles_or_nothing_can_be_known(case):
    rig = make_rig(40, 30, focal_px=500.0, baseline_m=0.1)
    dmap = {"far from the end": _dmap(20.0), "plain array": _dmap(62.5).disparity, "told not to": _dmap(62.5)}[case]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        objs = localize(BOX, dmap, rig, box_shrink=0.0, range_warning=case != "told not to")
    assert objs.status == ("ok",)


def test_piled_boxes_counts_the_share_of_known_pixels():
    dmap = _dmap(20.0, piled_rows=0)
    dmap.measured_disparity[5:25, 10:30] = np.nan
    dmap.measured_disparity[5, 10:30] = 63.0  # 20 of 20 known pixels piled
    assert piled_boxes(dmap, BOX, 0.0).tolist() == [True]
    below = _dmap(20.0)
    below.measured_disparity[5, 10:29] = 63.0  # 19 of 400: 4.75 % < 5 %
    assert piled_boxes(below, BOX, 0.0).tolist() == [False]
    below.measured_disparity[6, 10] = 62.0  # 20 of 400: 5 % (within 1 px of the end counts)
    assert piled_boxes(below, BOX, 0.0).tolist() == [True]


def test_localizer_with_its_checks_does_not_warn_twice(shared_data, yolox_nano):
    import calib
    import stereo_classic as sc

    pair = shared_data / "kitti_object_pair"
    rig = calib.load_rig(pair / "calib.txt")
    left, right = sc.read_image(pair / "left.png"), sc.read_image(pair / "right.png")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RangeWarning)
        with sc.Localizer(rig, yolox_nano, {"num_disparities": 128}) as loc:
            result = loc(left, right)
    assert "beyond_range" in result.objects.status
    dmap = sc.compute_disparity(left, right, num_disparities=128)
    with pytest.warns(RangeWarning, match="car at 3.3"):
        sc.localize(result.detections, dmap, rig, rng=0)
