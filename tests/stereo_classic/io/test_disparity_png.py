"""stereo_classic.io.disparity_png: KITTI x256 disparity and depth PNGs, Middlebury scaled maps."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from stereo_classic.io import (
    FileFormatError,
    read_kitti_depth,
    read_kitti_disparity,
    read_scaled_disparity,
    write_image,
    write_kitti_depth,
    write_kitti_disparity,
    write_scaled_disparity,
)

HYP = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def test_kitti_disparity_round_trip_and_encoding(tmp_path: Path) -> None:
    d = np.array([[0.0, 1.0, 1.5, np.nan], [10.25, 100.0, 255.99, 3.0 / 256]], np.float32)
    write_kitti_disparity(tmp_path / "k.png", d)
    raw = cv2.imread(str(tmp_path / "k.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16
    assert raw.tolist() == [[1, 256, 384, 0], [2624, 25600, 65533, 3]]  # x256, 0 unknown, 0 px kept as 1
    got = read_kitti_disparity(tmp_path / "k.png")
    assert got.dtype == np.float32 and np.isnan(got[0, 3])
    np.testing.assert_allclose(got[1], d[1], atol=1 / 512)


def test_kitti_disparity_errors(tmp_path: Path) -> None:
    for bad in (np.array([[-1.0]]), np.array([[np.inf]]), np.array([[256.5]])):
        with pytest.raises(ValueError, match="disparity"):
            write_kitti_disparity(tmp_path / "k.png", bad)
    with pytest.raises(ValueError, match="shape"):
        write_kitti_disparity(tmp_path / "k.png", np.zeros((2, 2, 3)))
    with pytest.raises(ValueError, match=r"\.png"):
        write_kitti_disparity(tmp_path / "k.jpg", np.zeros((2, 2)))
    write_image(tmp_path / "eight.png", np.zeros((3, 3), np.uint8))
    with pytest.raises(FileFormatError, match="16-bit"):
        read_kitti_disparity(tmp_path / "eight.png")
    write_image(tmp_path / "rgb.png", np.dstack([np.zeros((3, 3), np.uint16), np.ones((3, 3), np.uint16), np.zeros((3, 3), np.uint16)]))
    with pytest.raises(FileFormatError, match="single-channel"):
        read_kitti_disparity(tmp_path / "rgb.png")
    with pytest.raises(FileNotFoundError, match="missing.png"):
        read_kitti_disparity(tmp_path / "missing.png")


@HYP
@given(
    d=hnp.arrays(
        np.float64,
        st.tuples(st.integers(1, 8), st.integers(1, 8)),
        elements=st.one_of(st.floats(0, 255.99), st.just(np.nan), st.floats(-1e6, -1e-9), st.just(np.inf)),
    )
)
def test_kitti_round_trip_property(tmp_path: Path, d: np.ndarray) -> None:
    path = tmp_path / "k.png"
    if (d[~np.isnan(d)] < 0).any() or np.isinf(d).any():
        with pytest.raises(ValueError, match="disparity"):
            write_kitti_disparity(path, d)
        return
    write_kitti_disparity(path, d)
    got = read_kitti_disparity(path)
    assert got.shape == d.shape and got.dtype == np.float32
    np.testing.assert_array_equal(np.isnan(got), np.isnan(d))
    known = ~np.isnan(d)
    assert np.all(np.abs(got[known] - np.maximum(d[known], 1 / 256)) <= 1 / 512 + 1e-6)


def test_kitti_depth_round_trip_and_encoding(tmp_path: Path) -> None:
    z = np.array([[0.001, 1.0, 12.5, np.nan], [80.25, 255.99, 3.0 / 256, 7.0]], np.float32)
    write_kitti_depth(tmp_path / "z.png", z)
    raw = cv2.imread(str(tmp_path / "z.png"), cv2.IMREAD_UNCHANGED)
    assert raw.dtype == np.uint16
    assert raw.tolist() == [[1, 256, 3200, 0], [20544, 65533, 3, 1792]]  # metres x256, 0 unknown, tiny kept as 1
    got = read_kitti_depth(tmp_path / "z.png")
    assert got.shape == (2, 4) and got.dtype == np.float32
    np.testing.assert_array_equal(np.isnan(got), np.isnan(z))
    np.testing.assert_allclose(got[1], z[1], atol=1 / 512)
    assert got[0, 0] == np.float32(1 / 256)


def test_kitti_depth_errors(tmp_path: Path) -> None:
    for bad in (np.array([[0.0]]), np.array([[-2.0]]), np.array([[np.inf]]), np.array([[300.0]])):
        with pytest.raises(ValueError, match="depth"):
            write_kitti_depth(tmp_path / "z.png", bad)
    with pytest.raises(ValueError, match="shape"):
        write_kitti_depth(tmp_path / "z.png", np.ones((2, 2, 3)))
    with pytest.raises(ValueError, match=r"\.png"):
        write_kitti_depth(tmp_path / "z.jpg", np.ones((2, 2)))
    with pytest.raises(TypeError, match="depth"):
        write_kitti_depth(tmp_path / "z.png", [[1.0]])  # type: ignore[arg-type]
    assert not (tmp_path / "z.png").exists()
    write_image(tmp_path / "eight.png", np.ones((3, 3), np.uint8))
    with pytest.raises(FileFormatError, match="16-bit"):
        read_kitti_depth(tmp_path / "eight.png")
    with pytest.raises(FileNotFoundError, match="missing.png"):
        read_kitti_depth(tmp_path / "missing.png")


@HYP
@given(
    z=hnp.arrays(
        np.float64,
        st.tuples(st.integers(1, 8), st.integers(1, 8)),
        elements=st.one_of(st.floats(1 / 256, 255.99), st.just(np.nan)),
    )
)
def test_kitti_depth_round_trip_property(tmp_path: Path, z: np.ndarray) -> None:
    write_kitti_depth(tmp_path / "z.png", z)
    got = read_kitti_depth(tmp_path / "z.png")
    np.testing.assert_array_equal(np.isnan(got), np.isnan(z))
    known = ~np.isnan(z)
    assert np.all(np.abs(got[known] - z[known]) <= 1 / 512 + 1e-6)


@pytest.mark.parametrize(("scale", "bits", "ext"), [(16, 8, ".pgm"), (8, 8, ".pgm"), (4, 8, ".png"), (1, 8, ".png"), (64, 16, ".png")])
def test_scaled_disparity_round_trip(tmp_path: Path, scale: float, bits: int, ext: str) -> None:
    top = (255 if bits == 8 else 65535) / scale
    rng = np.random.default_rng(4)
    d = np.round(rng.uniform(0.5, top, (9, 11)) * scale) / scale
    d[0, 0] = np.nan
    path = tmp_path / f"d{ext}"
    write_scaled_disparity(path, d, scale, bits=bits)
    got = read_scaled_disparity(path, scale)
    assert got.dtype == np.float32 and np.isnan(got[0, 0])
    np.testing.assert_allclose(got[1:], d[1:], rtol=1e-6)


def test_scaled_disparity_errors(tmp_path: Path) -> None:
    write_image(tmp_path / "d.png", np.zeros((2, 2), np.uint8))
    for bad in (0, -1, np.nan, np.inf):
        with pytest.raises(ValueError, match="scale"):
            read_scaled_disparity(tmp_path / "d.png", bad)
    with pytest.raises(TypeError, match="scale"):
        read_scaled_disparity(tmp_path / "d.png", "4")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="8-bit"):
        write_scaled_disparity(tmp_path / "e.png", np.full((2, 2), 100.0), 4)
    with pytest.raises(ValueError, match="bits"):
        write_scaled_disparity(tmp_path / "e.png", np.ones((2, 2)), 4, bits=12)
    write_image(tmp_path / "c.png", np.dstack([np.zeros((2, 2), np.uint8), np.ones((2, 2), np.uint8), np.zeros((2, 2), np.uint8)]))
    with pytest.raises(FileFormatError, match="single-channel"):
        read_scaled_disparity(tmp_path / "c.png", 1)
    (tmp_path / "t.pgm").write_bytes(b"P5\n100 100\n255\n" + b"\1" * 50)
    with pytest.raises(FileFormatError, match="t.pgm"):
        read_scaled_disparity(tmp_path / "t.pgm", 16)
    assert not (tmp_path / "e.png").exists()
