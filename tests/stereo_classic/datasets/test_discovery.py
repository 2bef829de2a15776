"""stereo_classic.datasets.discovery: every folder of ../shared/data, layout sniffing, clear errors."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from stereo_classic.datasets import iter_scenes, load_middlebury2014, load_named_pair, load_scene
from stereo_classic.io import FileFormatError, write_image


def _pair(rng: np.random.Generator, h: int = 20, w: int = 30) -> tuple[np.ndarray, np.ndarray]:
    return rng.integers(0, 256, (h, w, 3), dtype=np.uint8), rng.integers(0, 256, (h, w, 3), dtype=np.uint8)


def test_every_shared_folder_loads(shared_data: Path, check_scene: Callable[..., None]) -> None:
    scenes = list(iter_scenes(shared_data))
    by_layout: dict[str, int] = {}
    for s in scenes:
        by_layout[s.layout] = by_layout.get(s.layout, 0) + 1
        check_scene(s, s.left.shape[:2])
        assert s.max_disparity is not None and s.max_disparity > 0
    assert by_layout == {
        "named_pair": 1,
        "kitti_lidar": 1,
        "middlebury2001": 6,
        "middlebury2003": 2,
        "middlebury2005/2006": 10,
        "middlebury2014": 1,
        "oakd": 12,
        "drivingstereo": 10,
    }
    # every folder holding files is covered by some scene; DrivingStereo nests its files below the
    # dataset root (<root>/<kind>/<sequence>/<frame>), which is the path of each of its scenes
    covered = {s.path.resolve() for s in scenes}
    nested = {s.path.resolve() for s in scenes if s.layout == "drivingstereo"}
    assert nested == {(shared_data / "drivingstereo").resolve()}
    folders = {p.parent.resolve() for p in shared_data.rglob("*.png")}
    flat = {f for f in folders if not any(root in f.parents for root in nested)}
    assert flat <= covered
    assert len(folders - flat) == 2  # train-disparity-map/<seq>, train-depth-map/<seq>
    with pytest.raises(ValueError, match="iter_scenes"):
        load_scene(shared_data / "middlebury2014")


def test_mismatched_files_are_clear_errors(tmp_path: Path) -> None:
    rng = np.random.default_rng(9)
    left, _ = _pair(rng)
    write_image(tmp_path / "im0.png", left)
    write_image(tmp_path / "im1.png", left[:10])
    with pytest.raises(FileFormatError, match="im1.png"):
        load_scene(tmp_path)
    write_image(tmp_path / "im1.png", left)
    (tmp_path / "disp0GT.pfm").write_bytes(b"Pf\n3 3\n-1.0\n" + b"\0" * 36)
    with pytest.raises(FileFormatError, match="disp0GT.pfm"):
        load_scene(tmp_path)
    (tmp_path / "disp0GT.pfm").write_bytes(b"Pf\n3 3\n-1.0\n" + b"\0" * 10)
    with pytest.raises(FileFormatError, match="truncated"):
        load_scene(tmp_path)
    with pytest.raises(FileFormatError, match="truncated"):
        list(iter_scenes(tmp_path))
    with pytest.warns(UserWarning, match="disp0GT.pfm"):
        assert list(iter_scenes(tmp_path, skip_errors=True)) == []


def test_load_scene_errors(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="nowhere"):
        load_scene(tmp_path / "nowhere")
    with pytest.raises(FileFormatError, match="no supported stereo layout"):
        load_scene(tmp_path)
    (tmp_path / "notes.txt").write_text("x")
    with pytest.raises(ValueError, match="is a file"):
        load_scene(tmp_path / "notes.txt")
    with pytest.raises(TypeError, match="path"):
        load_scene(3)  # type: ignore[arg-type]
    with pytest.raises(NotADirectoryError):
        load_middlebury2014(tmp_path / "notes.txt")
    assert list(iter_scenes(tmp_path)) == []


def test_named_pair_needs_a_name_when_ambiguous(tmp_path: Path) -> None:
    rng = np.random.default_rng(10)
    for name in ("a", "b"):
        left, right = _pair(rng)
        write_image(tmp_path / f"{name}_left.png", left)
        write_image(tmp_path / f"{name}_right.png", right)
    with pytest.raises(ValueError, match="`name`"):
        load_named_pair(tmp_path)
    assert load_named_pair(tmp_path, "b").gt_disparity is None
    assert [s.name for s in iter_scenes(tmp_path)] == ["a", "b"]
    (tmp_path / "stereodemo_calibration.json").write_text(
        json.dumps({"width": 30, "height": 20, "baseline_meters": 0.1, "fx": 50.0, "fy": 50.0, "cx0": 15.0, "cx1": 15.0, "cy": 10.0})
    )
    s = load_scene(tmp_path / "a")
    assert s.layout == "oakd" and s.max_disparity is None and s.rig.baseline_m == pytest.approx(0.1)
