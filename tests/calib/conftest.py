"""Fixtures of the calib tests: a raw stereo rig with distortion and a small rotation, the real image pairs."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from calib import StereoRig


@pytest.fixture(scope="session")
def stereo_rig() -> StereoRig:
    """A 640x480 rig, baseline about 12 cm, distinct cameras, 5-coefficient distortion: what the readers
    and writers must carry exactly."""
    k1 = np.array([[700.5, 0.0, 320.25], [0.0, 701.0, 239.75], [0.0, 0.0, 1.0]])
    k2 = np.array([[698.0, 0.1, 322.0], [0.0, 699.5, 241.0], [0.0, 0.0, 1.0]])
    d1 = np.array([-0.11, 0.021, 0.0011, -0.0007, 0.003])
    d2 = np.array([-0.1, 0.018, -0.0003, 0.0009, 0.0])
    r = cv2.Rodrigues(np.array([0.003, -0.012, 0.0017]))[0]
    t = np.array([-0.1203, 0.0011, -0.0004])
    return StereoRig(k1, d1, k2, d2, r, t, (640, 480))


def _read_pair(left_path: Path, right_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Skip only when the shared images are absent; images that exist must decode."""
    if not (left_path.is_file() and right_path.is_file()):
        pytest.skip(f"{left_path.parent} not available")
    left, right = cv2.imread(str(left_path)), cv2.imread(str(right_path))
    assert left is not None, f"{left_path} exists but cannot be decoded"
    assert right is not None, f"{right_path} exists but cannot be decoded"
    return left, right


@pytest.fixture
def motorcycle_pair(shared_data: Path) -> tuple[Path, np.ndarray, np.ndarray]:
    """(folder, left, right) of Middlebury 2014 Motorcycle (quarter size), BGR uint8."""
    d = shared_data / "middlebury2014" / "trainingQ" / "Motorcycle"
    return d, *_read_pair(d / "im0.png", d / "im1.png")


@pytest.fixture
def kitti_pair(shared_data: Path) -> tuple[np.ndarray, np.ndarray]:
    """(left, right) of the KITTI object pair, BGR uint8."""
    return _read_pair(shared_data / "kitti_object_pair/left.png", shared_data / "kitti_object_pair/right.png")
