"""benchmarks.guide_cost on a small folder laid out like the OAK-D one (two rendered pairs)."""

from __future__ import annotations

import json

import cv2

from benchmarks import guide_cost
from tests.helpers import walk_scenes as ws


def test_measure_and_main(tmp_path, capsys):
    frames, rig = ws.approach(n=2)
    for i, (left, right, _, _) in enumerate(frames):
        cv2.imwrite(str(tmp_path / f"s{i}_left.png"), left)
        cv2.imwrite(str(tmp_path / f"s{i}_right.png"), right)
    (tmp_path / "stereodemo_calibration.json").write_text(json.dumps({
        "width": 320, "height": 240, "baseline_meters": rig.baseline_m, "fx": rig.focal_px, "fy": rig.focal_px,
        "cx0": rig.cx_left, "cx1": rig.cx_right, "cy": rig.cy}))
    result = guide_cost.measure(tmp_path, repeat=1, model=None)
    assert result["frames"] == 2 and 0 < result["guide_cpu_median_ms"] and 0 < result["guide_median_ms"]
    still = guide_cost.measure(tmp_path, repeat=1, model=None, still=3, vertical_lines=False)
    assert still["frames"] == 6
    assert guide_cost.main(["--data", str(tmp_path), "--repeat", "1"]) == 0
    assert "ms CPU per 320x240 frame" in capsys.readouterr().out
    assert guide_cost.main(["--data", str(tmp_path / "absent")]) == 2
    assert guide_cost.main(["--data", str(tmp_path), "--still", "-1"]) == 2
