"""benchmarks.scenes: dataset families and short names."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.scenes import (
    FAMILIES,
    BenchScene,
    load_scenes,
    scene_family,
    short_name,
)


@pytest.mark.parametrize(
    ("name", "source", "family"),
    [
        ("Adirondack", "/work/shared/data/adirondackQ", "Middlebury-style"),
        ("Motorcycle", "/d/middlebury2014/trainingQ/Motorcycle", "Middlebury-style"),
        ("tsukuba", "/d/middlebury2001/tsukuba", "Middlebury-style"),
        ("Motorcycle", "built-in demo (skimage.data.stereo_motorcycle)", "Middlebury-style"),
        ("x_y", "/d/drivingstereo", "driving"),
        ("kitti_object_pair", "/d/kitti_object_pair", "driving"),
        ("selfie", "/d/oakd", "indoor"),
        ("a", "/home/kitti_fan/middlebury2014/x", "Middlebury-style"),  # the nearest folder decides
        ("a", "/tmp/b", "other"),
        ("Baby1", "/d/middlebury2005_2006/Baby1", "Middlebury 2005/2006"),
        ("sawtooth", "/d/middlebury2001/sawtooth", "Middlebury 2001 planar"),
        ("venus", "/d/middlebury2001/venus", "Middlebury-style"),  # one of the six developer scenes
        ("barn1", "/d/elsewhere/barn1", "other"),  # the planar rows need the Middlebury 2001 folder
    ],
)
def test_scene_family(name, source, family):
    assert scene_family(name, source) == family


def test_bench_scene_family_derived_or_checked():
    img = np.zeros((4, 4), np.uint8)
    assert BenchScene("t", img, img, source="/d/drivingstereo").family == "driving"
    assert BenchScene("t", img, img, family="indoor").family == "indoor"
    with pytest.raises(ValueError, match="`family` must be one of"):
        BenchScene("t", img, img, family="outdoors")
    assert FAMILIES[:2] == ("Middlebury-style", "driving")


def test_short_names():
    assert short_name("2018-07-09-16-11-56_2018-07-09-16-11-59-004") == "16-11-59-004"
    assert short_name("cones") == "cones" and short_name("a_b") == "a_b"


def test_shared_middlebury_families_keep_the_six_developer_scenes(shared_data):
    families: dict[str, list[str]] = {}
    for s in load_scenes(shared_data):
        families.setdefault(s.family, []).append(s.name.lower())
    assert sorted(families["Middlebury-style"]) == ["adirondack", "cones", "motorcycle", "teddy", "tsukuba", "venus"]
    assert sorted(families["Middlebury 2001 planar"]) == ["barn1", "barn2", "poster", "sawtooth"]
    assert len(families["Middlebury 2005/2006"]) == 10


def test_shared_scenes_have_their_families(shared_data):
    families = {s.name: s.family for s in load_scenes(shared_data, ["teddy", "16-11-57-101", "kitti", "Adirondack"])}
    assert families["teddy"] == families["Adirondack"] == "Middlebury-style"
    assert families["kitti_object_pair"] == "driving"
    assert [f for n, f in families.items() if n.endswith("16-11-57-101")] == ["driving"]
