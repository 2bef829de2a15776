"""stereo_classic.io.ply: round trips with colour order, ASCII and big-endian files, hostile headers."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from stereo_classic.io import FileFormatError, read_ply, write_ply

HYP = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def test_ply_round_trip_with_colour_order(tmp_path: Path) -> None:
    rng = np.random.default_rng(5)
    pts = rng.normal(size=(50, 3)).astype(np.float32)
    bgr = rng.integers(0, 256, (50, 3), dtype=np.uint8)
    n = write_ply(tmp_path / "c.ply", pts, bgr)
    assert n == 50
    data = (tmp_path / "c.ply").read_bytes()
    header, body = data.split(b"end_header\n", 1)
    assert b"format binary_little_endian 1.0" in header and len(body) == 50 * 15
    first = struct.unpack("<3f3B", body[:15])
    assert first[3:] == tuple(bgr[0, ::-1])  # stored as red, green, blue
    cloud = read_ply(tmp_path / "c.ply")
    np.testing.assert_array_equal(cloud.points, pts)
    np.testing.assert_array_equal(cloud.colors, bgr)
    pts2, rgb = read_ply(tmp_path / "c.ply", color_order="rgb")
    np.testing.assert_array_equal(rgb, bgr[:, ::-1])


def test_ply_drops_non_finite_points_and_takes_image_shaped_input(tmp_path: Path) -> None:
    pts = np.zeros((4, 5, 3), np.float32)
    pts[..., 2] = np.arange(20).reshape(4, 5)
    pts[0, 0] = np.nan
    pts[1, 1, 2] = np.inf
    colors = np.zeros((4, 5, 3), np.uint8)
    colors[..., 0] = np.arange(20).reshape(4, 5)
    assert write_ply(tmp_path / "i.ply", pts, colors) == 18
    cloud = read_ply(tmp_path / "i.ply")
    assert cloud.points.shape == (18, 3)
    np.testing.assert_array_equal(cloud.points[:, 2], cloud.colors[:, 0])  # colours follow their points
    with pytest.raises(ValueError, match="NaN"):
        write_ply(tmp_path / "j.ply", pts, drop_invalid=False)
    assert write_ply(tmp_path / "nocolor.ply", pts[2]) == 5
    assert read_ply(tmp_path / "nocolor.ply").colors is None


def test_ply_reads_ascii_and_big_endian(tmp_path: Path) -> None:
    (tmp_path / "a.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nelement face 0\n"
        "property list uchar int vertex_indices\nend_header\n1 2 3 255 0 0\n4 5 6 0 0 255\n"
    )
    pts, bgr = read_ply(tmp_path / "a.ply")
    np.testing.assert_array_equal(pts, [[1, 2, 3], [4, 5, 6]])
    np.testing.assert_array_equal(bgr, [[0, 0, 255], [255, 0, 0]])
    head = b"ply\nformat binary_big_endian 1.0\nelement vertex 1\nproperty double x\nproperty double y\nproperty double z\nend_header\n"
    (tmp_path / "b.ply").write_bytes(head + struct.pack(">3d", 1.5, -2.0, 7.0))
    np.testing.assert_array_equal(read_ply(tmp_path / "b.ply").points, [[1.5, -2.0, 7.0]])


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"", "empty"),
        (b"not a ply", "not a PLY"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n", "end_header"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 1000000000000\nproperty float x\nproperty float y\n"
         b"property float z\nend_header\n" + b"\0" * 12, "truncated"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
         b"property float z\nend_header\n" + b"\0" * 23, "truncated"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n"
         + b"\0" * 8, "x, y, z"),
        (b"ply\nformat binary_middle_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
         b"property float z\nend_header\n", "format"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex -1\nproperty float x\nend_header\n", "negative"),
        (b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty quad x\nend_header\n", "unsupported"),
        (b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
         b"end_header\n1 2 3\n", "truncated"),
    ],
)
def test_ply_hostile_files(tmp_path: Path, content: bytes, match: str) -> None:
    path = tmp_path / "bad.ply"
    path.write_bytes(content)
    with pytest.raises(FileFormatError, match=match) as info:
        read_ply(path)
    assert "bad.ply" in str(info.value)


def test_ply_writer_errors(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="points"):
        write_ply(tmp_path / "a.ply", np.zeros((4, 2)))
    with pytest.raises(ValueError, match="colors"):
        write_ply(tmp_path / "a.ply", np.zeros((4, 3)), np.zeros((3, 3), np.uint8))
    with pytest.raises(ValueError, match="uint8"):
        write_ply(tmp_path / "a.ply", np.zeros((4, 3)), np.zeros((4, 3), np.float32))
    with pytest.raises(ValueError, match="color_order"):
        write_ply(tmp_path / "a.ply", np.zeros((4, 3)), color_order="rbg")
    with pytest.raises(FileNotFoundError):
        read_ply(tmp_path / "nothing.ply")
    assert not (tmp_path / "a.ply").exists()


@HYP
@given(
    pts=hnp.arrays(np.float32, st.tuples(st.integers(0, 30), st.just(3)), elements=st.floats(width=32, allow_nan=True, allow_infinity=True)),
    with_colors=st.booleans(),
)
def test_ply_round_trip_property(tmp_path: Path, pts: np.ndarray, with_colors: bool) -> None:
    colors = (np.arange(pts.size, dtype=np.int64).reshape(-1, 3) % 256).astype(np.uint8) if with_colors else None
    n = write_ply(tmp_path / "p.ply", pts, colors)
    keep = np.isfinite(pts).all(axis=1)
    assert n == int(keep.sum())
    cloud = read_ply(tmp_path / "p.ply")
    np.testing.assert_array_equal(cloud.points, pts[keep])
    if with_colors:
        np.testing.assert_array_equal(cloud.colors, colors[keep])
    else:
        assert cloud.colors is None
