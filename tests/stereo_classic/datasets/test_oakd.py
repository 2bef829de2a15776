"""stereo_classic.datasets.oakd: the twelve OAK-D pairs, rig and depth range from the JSON."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from calib import CalibrationError
from stereo_classic.datasets import iter_oakd, load_oakd, load_scene
from stereo_classic.io import write_image


def _pair(rng: np.random.Generator, h: int = 20, w: int = 30) -> tuple[np.ndarray, np.ndarray]:
    return rng.integers(0, 256, (h, w, 3), dtype=np.uint8), rng.integers(0, 256, (h, w, 3), dtype=np.uint8)


def test_oakd_pairs_and_rig(shared_data: Path, check_scene: Callable[..., None]) -> None:
    scenes = list(iter_oakd(shared_data / "oakd"))
    assert len(scenes) == 12
    names = [s.name for s in scenes]
    assert names == sorted(names) and "selfie" in names
    for s in scenes:
        check_scene(s, (480, 640))
        assert s.gt_disparity is None and s.layout == "oakd"
        assert (s.left[..., 0] == s.left[..., 1]).all()  # grey expanded to BGR
    rig = scenes[0].rig
    assert rig.baseline_m == pytest.approx(0.075) and rig.focal_px == pytest.approx(451.0344543457031)
    assert scenes[0].max_disparity == 48  # f B / 1.0 m = 33.8 px -> 48
    by_name = load_scene(shared_data / "oakd" / "toy")
    by_file = load_scene(shared_data / "oakd" / "toy_left.png")
    np.testing.assert_array_equal(by_name.left, by_file.left)
    with pytest.raises(ValueError, match="12 scenes"):
        load_scene(shared_data / "oakd")
    with pytest.raises(FileNotFoundError, match="nothing_left"):
        load_oakd(shared_data / "oakd", "nothing")


@pytest.mark.parametrize("depth_range", [[0, 5], [2.0, 1.0], ["1", 5], [1.0], "near"])
def test_oakd_bad_depth_range_is_an_error(tmp_path: Path, depth_range: object) -> None:
    left, right = _pair(np.random.default_rng(12))
    write_image(tmp_path / "a_left.png", left)
    write_image(tmp_path / "a_right.png", right)
    calib = {"width": 30, "height": 20, "baseline_meters": 0.1, "fx": 50.0, "cx0": 15.0, "cx1": 15.0, "cy": 10.0}
    path = tmp_path / "stereodemo_calibration.json"
    path.write_text(json.dumps({**calib, "depth_range": [0.25, 5.0]}))
    assert load_oakd(tmp_path, "a").max_disparity == 32  # 50 * 0.1 / 0.25 = 20 px -> 32
    path.write_text(json.dumps({**calib, "depth_range": depth_range}))  # was silently ignored
    with pytest.raises(CalibrationError, match="`depth_range`"):
        load_oakd(tmp_path, "a")
