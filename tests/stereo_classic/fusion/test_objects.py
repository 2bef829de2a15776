"""Tests for stereo_classic.fusion.objects: LocalizedObjects (shapes, selection, checks) and direction_phrase."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_classic.fusion import FusionInputError, LocalizedObjects, direction_phrase, localize
from tests.helpers.scenes import make_rig


def test_result_shapes_dtypes_and_selection():
    rig = make_rig(40, 30, focal_px=500.0, baseline_m=0.1)
    d = np.full((30, 40), 10.0, np.float32)
    objs = localize(np.array([[0, 0, 20, 20], [50, 50, 60, 60], [10, 10, 40, 30]]), d, rig)
    assert objs.xyz.shape == (3, 3) and objs.xyxy.dtype == np.float32 and objs.inliers.dtype == np.int64
    assert objs.distance_m.dtype == np.float64 and objs.confidence.dtype == np.float32
    assert objs.ok.tolist() == [True, False, True]
    sub = objs[objs.ok]
    assert len(sub) == 2 and sub.status == ("ok", "ok")
    assert objs[1].status == ("empty_box",)
    with pytest.raises(FusionInputError, match="status"):
        LocalizedObjects(**{**objs.__dict__, "status": ("ok", "ok", "bogus")})
    with pytest.raises(FusionInputError, match="xyz"):
        LocalizedObjects(**{**objs.__dict__, "xyz": np.zeros((2, 3))})


def test_direction_phrase():
    assert direction_phrase([0.0, 0.0, 2.0]) == "ahead"
    assert direction_phrase([-0.5, 0.0, 3.0]) == "slightly left"
    assert direction_phrase([0.5, 0.0, 3.0]) == "slightly right"
    assert direction_phrase([3.0, 0.0, 3.0]) == "right"
    assert direction_phrase([np.nan, 0.0, 3.0]) == ""


def test_format_table_has_a_header_and_aligned_columns():
    from stereo_classic.fusion.objects import TABLE_COLUMNS

    rig = make_rig(40, 30, focal_px=500.0, baseline_m=0.1)
    d = np.full((30, 40), 10.0, np.float32)
    objs = localize(np.array([[0, 0, 20, 20], [50, 50, 60, 60]]), d, rig)
    lines = objs.format_table().splitlines()
    assert len(lines) == 3
    assert lines[0].startswith("label") and all(c in lines[0] for c in TABLE_COLUMNS)
    assert lines[0].index("direction") == lines[1].index("ahead") == lines[2].index("distance unknown")
    assert lines[1].split()[:4] == ["object", "1.00", "5.00", "m"] and "?" in lines[2].split()
    assert [r.split() for r in objs.format_table(header=False).splitlines()] == [r.split() for r in lines[1:]]
    assert LocalizedObjects.empty().format_table() == ""
