"""benchmarks.guide_ground on a small folder laid out like the OAK-D one (a rendered pair of a known floor)."""

from __future__ import annotations

import json
import re

import cv2
import pytest

from benchmarks import guide_ground
from tests.helpers import walk_scenes as ws


def test_measure_and_main(tmp_path, capsys):
    frames, rig = ws.approach(n=1)
    left, right, _, _ = frames[0]
    cv2.imwrite(str(tmp_path / "walk_left.png"), left)
    cv2.imwrite(str(tmp_path / "walk_right.png"), right)
    (tmp_path / "stereodemo_calibration.json").write_text(json.dumps({
        "width": 320, "height": 240, "baseline_meters": rig.baseline_m, "fx": rig.focal_px, "fy": rig.focal_px,
        "cx0": rig.cx_left, "cx1": rig.cx_right, "cy": rig.cy}))
    (row,) = guide_ground.measure(tmp_path, frames=2, model=None, save=tmp_path / "pics", seeds=2)
    assert len(row["seeded"]) == 2 and all(abs(h - 1.2) < 0.05 for h, _ in row["seeded"])
    assert row["scene"] == "walk" and row["height_m"] == pytest.approx(1.2, abs=0.05)
    assert row["pitch_deg"] == pytest.approx(10.0, abs=1.5) and len(row["heights"]) == 2
    assert (tmp_path / "pics" / "walk_overlay.png").is_file() and (tmp_path / "pics" / "walk_birdseye.png").is_file()
    assert guide_ground.main(["--data", str(tmp_path), "--frames", "1", "--seeds", "2"]) == 0
    out = capsys.readouterr().out
    assert "| walk | 1.2" in out and "seeds 0-1" in out and "(2/2) |" in out
    assert guide_ground.main(["--data", str(tmp_path / "absent")]) == 2
    assert guide_ground.main(["--data", str(tmp_path), "--frames", "0"]) == 2


def test_vertical_lines_column(tmp_path, capsys):
    left, right, _, rig = ws.render(ws.floor() + ws.poles(), supersample=1, **ws.CAMERA)
    cv2.imwrite(str(tmp_path / "poles_left.png"), left)
    cv2.imwrite(str(tmp_path / "poles_right.png"), right)
    (tmp_path / "stereodemo_calibration.json").write_text(json.dumps({
        "width": 320, "height": 240, "baseline_meters": rig.baseline_m, "fx": rig.focal_px, "fy": rig.focal_px,
        "cx0": rig.cx_left, "cx1": rig.cx_right, "cy": rig.cy}))
    (row,) = guide_ground.measure(tmp_path, frames=1, model=None)
    assert row["gravity"].pitch_deg == pytest.approx(10.0, abs=1.0) and row["angle_deg"] < 2.0
    (off,) = guide_ground.measure(tmp_path, frames=1, model=None, vertical_lines=False)
    assert off["gravity"] is None and off["angle_deg"] is None
    assert guide_ground.main(["--data", str(tmp_path), "--frames", "1"]) == 0
    assert re.search(r"\| poles \| 1\.\d\d \|.*\| (9|10)\.\d / -?0\.\d \(\d+\) \| [01]\.\d \|", capsys.readouterr().out)
    assert guide_ground.main(["--data", str(tmp_path), "--frames", "1", "--no-vertical-lines"]) == 0
    assert re.search(r"\| poles \| 1\.\d\d \| [\d.]+ \| -?[\d.]+ \| - \| - \|", capsys.readouterr().out)
