"""benchmarks.road_scenes and benchmarks.object_errors (issue 31): rendered ground truth and the per-object table."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.object_errors import _detections, render_markdown, summarise
from benchmarks.road_scenes import DRIVING_RIG, car, person, render_road_scene


@pytest.fixture(scope="module")
def scenes():
    return [render_road_scene([car(3.5, 45.0, 1), car(-3.5, 14.0, 2, tone=160.0)], name="car", n_targets=1),
            render_road_scene([person(-3.0, 25.0, 3), car(0.0, 33.0, 4)], name="person", n_targets=1)]


def test_rendered_scene_has_the_driving_rig_and_its_ground_truth(scenes):
    s = scenes[0]
    assert s.left.shape == (DRIVING_RIG["height"], DRIVING_RIG["width"], 3) and s.right.shape == s.left.shape
    assert s.rig.focal_px == DRIVING_RIG["focal_px"] and s.labels == ("car",)
    # the median depth of the car's pixels: its rear face at 45 m (the cabin 0.8 m behind is a smaller part)
    assert s.reference_m[0] == pytest.approx(45.0, abs=0.5)
    x0, y0, x1, y1 = s.boxes[0]
    assert 30 < y1 - y0 < 50  # a far car: 1.45 m at 45 m is 32 px, and the detector's margin


def test_fusion_on_rendered_scenes_within_5_percent_and_covered(scenes):
    import stereo_classic as sc
    from stereo_classic.fusion import localize

    for s in scenes:
        dmap = sc.compute_disparity(s.left, s.right, num_disparities=96, threads=2)
        objs = localize(_detections(s.boxes, s.labels), dmap, s.rig, rng=0)
        err = abs(objs.distance_m[0] - s.reference_m[0])
        assert objs.status == ("ok",) and err / s.reference_m[0] < 0.05, s.name
        assert err <= 3 * objs.distance_sigma_m[0], s.name


def test_summary_counts_and_flags():
    rows = [{"set": "a", "frame": "f", "label": "car", "fusion": "after", "status": "ok", "error_pct": e,
             "covered": c, "reference_m": 10.0, "distance_m": 10.0, "sigma_m": 0.1}
            for e, c in ((1.0, True), (-2.0, True), (8.0, False))]
    rows.append({**rows[0], "status": "estimates_disagree", "error_pct": None, "covered": None, "distance_m": None})
    m = summarise(rows)
    assert m["objects"] == 4 and m["with_distance"] == 3 and m["median_pct"] == 2.0
    assert m["within_5_pct"] == pytest.approx(200 / 3) and m["ok_beyond_3_sigma"] == ["f car"]
    assert m["statuses"] == ["estimates_disagree"]
    assert "| a | after | 4 | 3 |" in render_markdown(rows) and np.isfinite(m["p90_pct"])
