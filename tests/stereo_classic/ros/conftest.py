"""The KITTI pair and ``run``'s objects on its image files: what the recordings and the node must reproduce."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

import calib
from stereo_classic.cli.main import main
from stereo_classic.io import read_image


@pytest.fixture(scope="session")
def kitti(shared_data: Path):
    folder = shared_data / "kitti_object_pair"
    if not folder.is_dir():
        pytest.skip("kitti_object_pair not in the shared data")
    rig = calib.load_rig(folder / "calib.txt")
    return folder, read_image(folder / "left.png"), read_image(folder / "right.png"), rig


@pytest.fixture(scope="session")
def files_objects(kitti, tmp_path_factory) -> list:
    """The objects of ``run`` on the image files (default detector, matcher and fusion settings)."""
    folder, *_ = kitti
    out = tmp_path_factory.mktemp("files")
    code = main(["run", "-q", "--left", str(folder / "left.png"), "--right", str(folder / "right.png"),
                 "--calib", str(folder / "calib.txt"), "--save", "json", "-o", str(out)])
    assert code == 0
    objects = json.loads((out / "left_objects.json").read_text())["objects"]
    assert len(objects) >= 3  # seven labelled cars: the comparisons are not of empty lists
    return objects
