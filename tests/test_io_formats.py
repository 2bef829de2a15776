"""stereo_classic.io: round trips, hostile files, atomic writes, property tests."""

from __future__ import annotations

import os
import struct
from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from stereo_classic.io import (
    FileFormatError,
    PointCloud,
    atomic_write,
    read_image,
    read_kitti_disparity,
    read_pfm,
    read_ply,
    read_scaled_disparity,
    write_image,
    write_kitti_disparity,
    write_pfm,
    write_ply,
    write_scaled_disparity,
)

HYP = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


# --------------------------------------------------------------------------------------------- images


@pytest.mark.parametrize("ext", [".png", ".bmp", ".pgm", ".tif"])
def test_image_round_trip_bgr_exact(tmp_path: Path, ext: str) -> None:
    rng = np.random.default_rng(1)
    img = rng.integers(0, 256, (23, 31, 3), dtype=np.uint8) if ext != ".pgm" else rng.integers(0, 256, (23, 31), dtype=np.uint8)
    path = tmp_path / f"a{ext}"
    write_image(path, img)
    got = read_image(path, grayscale=(ext == ".pgm"))
    assert got.dtype == np.uint8
    np.testing.assert_array_equal(got, img)


def test_image_16bit_kept_and_grey_expanded_to_bgr(tmp_path: Path) -> None:
    img16 = (np.arange(12 * 7, dtype=np.uint16).reshape(12, 7) * 700).astype(np.uint16)
    write_image(tmp_path / "g16.png", img16)
    got = read_image(tmp_path / "g16.png", grayscale=True)
    assert got.dtype == np.uint16
    np.testing.assert_array_equal(got, img16)
    grey = np.full((5, 6), 77, np.uint8)
    write_image(tmp_path / "g.png", grey)
    bgr = read_image(tmp_path / "g.png")
    assert bgr.shape == (5, 6, 3) and (bgr == 77).all()


def test_image_odd_path_characters(tmp_path: Path) -> None:
    folder = tmp_path / "dossier é ü 图像"
    folder.mkdir()
    img = np.zeros((4, 5, 3), np.uint8)
    img[1, 2] = (1, 2, 3)
    write_image(folder / "bild ß.png", img)
    np.testing.assert_array_equal(read_image(folder / "bild ß.png"), img)


def test_read_image_errors_name_the_path(tmp_path: Path) -> None:
    missing = tmp_path / "nope.png"
    with pytest.raises(FileNotFoundError, match="nope.png"):
        read_image(missing)
    with pytest.raises(FileNotFoundError, match="directory"):
        read_image(tmp_path)
    (tmp_path / "empty.png").write_bytes(b"")
    with pytest.raises(FileFormatError, match="empty.png.*|empty"):
        read_image(tmp_path / "empty.png")
    (tmp_path / "text.png").write_bytes(b"this is not an image at all")
    with pytest.raises(FileFormatError, match="text.png"):
        read_image(tmp_path / "text.png")
    with pytest.raises(TypeError, match="path"):
        read_image(42)  # type: ignore[arg-type]


@pytest.mark.parametrize("keep", [0.5, 0.9, 0.999])
def test_read_image_truncated_png(tmp_path: Path, keep: float) -> None:
    rng = np.random.default_rng(2)
    write_image(tmp_path / "full.png", rng.integers(0, 256, (40, 50, 3), dtype=np.uint8))
    data = (tmp_path / "full.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(FileFormatError, match="cut.png"):
        read_image(tmp_path / "cut.png")


def test_write_image_errors_leave_nothing(tmp_path: Path) -> None:
    img = np.zeros((4, 4, 3), np.uint8)
    with pytest.raises(ValueError, match="extension"):
        write_image(tmp_path / "noext", img)
    with pytest.raises(ValueError, match=r"\.xyz"):
        write_image(tmp_path / "a.xyz", img)
    with pytest.raises(ValueError, match="dtype"):
        write_image(tmp_path / "f.png", img.astype(np.float32))
    with pytest.raises(ValueError, match="shape"):
        write_image(tmp_path / "s.png", np.zeros((4, 4, 2), np.uint8))
    with pytest.raises(FileNotFoundError, match="does not exist"):
        write_image(tmp_path / "no" / "dir.png", img)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


# --------------------------------------------------------------------------------------------- atomic


def test_atomic_write_success_and_failure(tmp_path: Path) -> None:
    target = tmp_path / "out.bin"
    with atomic_write(target) as f:
        f.write(b"first")
    assert target.read_bytes() == b"first"
    with pytest.raises(RuntimeError):
        with atomic_write(target) as f:
            f.write(b"half-writ")
            raise RuntimeError("boom")
    assert target.read_bytes() == b"first"  # old content untouched
    assert _leftovers(tmp_path) == []
    new = tmp_path / "never.txt"
    with pytest.raises(KeyError):
        with atomic_write(new, "w") as f:
            f.write("x")
            raise KeyError("boom")
    assert not new.exists() and _leftovers(tmp_path) == []


def test_atomic_write_text_mode_and_permissions(tmp_path: Path) -> None:
    target = tmp_path / "t.txt"
    with atomic_write(target, "w") as f:
        f.write("é\n")
    assert target.read_bytes() == "é\n".encode()
    umask = os.umask(0)
    os.umask(umask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask


def test_atomic_write_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="mode"):
        with atomic_write(tmp_path / "a", "a"):
            pass
    with pytest.raises(IsADirectoryError):
        with atomic_write(tmp_path):
            pass
    with pytest.raises(FileNotFoundError, match="missing"):
        with atomic_write(tmp_path / "missing" / "a"):
            pass


def test_failed_writer_keeps_old_file(tmp_path: Path) -> None:
    path = tmp_path / "d.png"
    write_kitti_disparity(path, np.full((3, 3), 5.0, np.float32))
    before = path.read_bytes()
    with pytest.raises(ValueError):
        write_kitti_disparity(path, np.full((3, 3), -5.0, np.float32))
    assert path.read_bytes() == before and _leftovers(tmp_path) == []


# --------------------------------------------------------------------------------------------- PFM


@pytest.mark.parametrize("byteorder", ["little", "big"])
@pytest.mark.parametrize("shape", [(7, 5), (4, 6, 3)])
def test_pfm_round_trip(tmp_path: Path, byteorder: str, shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(size=shape).astype(np.float32)
    a.flat[0], a.flat[1], a.flat[2] = np.inf, -np.inf, np.nan
    write_pfm(tmp_path / "a.pfm", a, byteorder=byteorder)
    head = (tmp_path / "a.pfm").read_bytes()[:20]
    assert head.startswith(b"PF\n" if len(shape) == 3 else b"Pf\n")
    assert (b"\n-1.0\n" in head) == (byteorder == "little")
    b = read_pfm(tmp_path / "a.pfm")
    assert b.dtype == np.float32 and b.shape == shape and b.flags.c_contiguous
    np.testing.assert_array_equal(b, a)  # NaN == NaN for assert_array_equal


def test_pfm_rows_stored_bottom_up_and_scale_sign(tmp_path: Path) -> None:
    # hand-made file: 2 x 2, big-endian (positive scale), bottom row first
    body = struct.pack(">4f", 3.0, 4.0, 1.0, 2.0)
    (tmp_path / "h.pfm").write_bytes(b"Pf\n2 2\n2.5\n" + body)
    np.testing.assert_array_equal(read_pfm(tmp_path / "h.pfm"), [[1.0, 2.0], [3.0, 4.0]])
    body = struct.pack("<4f", 3.0, 4.0, 1.0, 2.0)
    (tmp_path / "l.pfm").write_bytes(b"Pf\n2 2\n-0.003922\n" + body)  # Middlebury writes -1/255
    np.testing.assert_array_equal(read_pfm(tmp_path / "l.pfm"), [[1.0, 2.0], [3.0, 4.0]])


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"Pf\n100000 100000\n-1.0\n" + b"\0" * 16, "truncated"),  # lying header: 40 GB promised
        (b"Pf\n2 2\n-1.0\n" + b"\0" * 15, "truncated"),
        (b"Pf\n2 2\n-1.0\n" + b"\0" * 17, "longer"),
        (b"PF\n2 2\n-1.0\n" + b"\0" * 16, "truncated"),  # colour needs 48 bytes
        (b"P6\n2 2\n255\n" + b"\0" * 12, "not a PFM"),
        (b"Pf\n0 2\n-1.0\n", "positive"),
        (b"Pf\n2 2\n0\n" + b"\0" * 16, "non-zero"),
        (b"Pf\n2 2\nnan\n" + b"\0" * 16, "finite"),
        (b"Pf\n2 2\nabc\n" + b"\0" * 16, "PFM"),
        (b"Pf\n-2 2\n-1.0\n" + b"\0" * 16, "not a PFM"),
    ],
)
def test_pfm_hostile_files(tmp_path: Path, content: bytes, match: str) -> None:
    path = tmp_path / "bad.pfm"
    path.write_bytes(content)
    with pytest.raises(FileFormatError, match=match) as info:
        read_pfm(path)
    assert "bad.pfm" in str(info.value)


def test_pfm_missing_empty_directory(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="x.pfm"):
        read_pfm(tmp_path / "x.pfm")
    (tmp_path / "e.pfm").write_bytes(b"")
    with pytest.raises(FileFormatError, match="empty"):
        read_pfm(tmp_path / "e.pfm")
    with pytest.raises(FileNotFoundError, match="directory"):
        read_pfm(tmp_path)


def test_write_pfm_rejects_bad_input(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="shape"):
        write_pfm(tmp_path / "a.pfm", np.zeros((2, 2, 2), np.float32))
    with pytest.raises(ValueError, match="empty"):
        write_pfm(tmp_path / "a.pfm", np.zeros((0, 2), np.float32))
    with pytest.raises(ValueError, match="dtype"):
        write_pfm(tmp_path / "a.pfm", np.zeros((2, 2), complex))
    with pytest.raises(ValueError, match="float32 range"):
        write_pfm(tmp_path / "a.pfm", np.full((2, 2), 1e300))
    with pytest.raises(ValueError, match="byteorder"):
        write_pfm(tmp_path / "a.pfm", np.zeros((2, 2), np.float32), byteorder="middle")
    with pytest.raises(TypeError, match="array"):
        write_pfm(tmp_path / "a.pfm", [[1.0]])  # type: ignore[arg-type]
    assert not (tmp_path / "a.pfm").exists()


@HYP
@given(
    a=hnp.arrays(
        np.float32,
        st.tuples(st.integers(1, 9), st.integers(1, 9)).flatmap(
            lambda hw: st.sampled_from([hw, hw + (3,)])
        ),
        elements=st.floats(width=32, allow_nan=True, allow_infinity=True),
    ),
    byteorder=st.sampled_from(["little", "big"]),
)
def test_pfm_round_trip_property(tmp_path: Path, a: np.ndarray, byteorder: str) -> None:
    path = tmp_path / "p.pfm"
    write_pfm(path, a, byteorder=byteorder)
    np.testing.assert_array_equal(read_pfm(path), a)


@HYP
@given(tail=st.binary(max_size=64), w=st.integers(0, 10**9), h=st.integers(0, 10**9))
def test_pfm_random_bodies_never_crash(tmp_path: Path, tail: bytes, w: int, h: int) -> None:
    path = tmp_path / "r.pfm"
    path.write_bytes(f"Pf\n{w} {h}\n-1.0\n".encode() + tail)
    try:
        out = read_pfm(path)
    except FileFormatError as exc:
        assert "r.pfm" in str(exc)
    else:
        assert out.shape == (h, w) and 4 * w * h == len(tail)


# --------------------------------------------------------------------------------------------- KITTI


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


# --------------------------------------------------------------------------------------------- scaled


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


# --------------------------------------------------------------------------------------------- PLY


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


@HYP
@given(junk=st.binary(max_size=200))
def test_readers_on_random_bytes_raise_only_documented_errors(tmp_path: Path, junk: bytes) -> None:
    for name, reader in (
        ("j.png", read_image),
        ("j.pfm", read_pfm),
        ("j.ply", read_ply),
        ("k.png", read_kitti_disparity),
        ("m.pgm", lambda p: read_scaled_disparity(p, 8)),
    ):
        path = tmp_path / name
        path.write_bytes(junk)
        try:
            out = reader(path)
        except FileFormatError as exc:
            assert name in str(exc)
        else:  # bytes that parse must give a well-formed result, not garbage
            _check_well_formed(name, out, len(junk))


def _check_well_formed(name: str, out: object, n_bytes: int) -> None:
    if name == "j.ply":
        assert isinstance(out, PointCloud)
        assert out.points.dtype == np.float32 and out.points.ndim == 2 and out.points.shape[1] == 3
        assert out.points.nbytes <= 4 * n_bytes  # at most one float per stored byte (ASCII "0 ")
        assert out.colors is None or (out.colors.dtype == np.uint8 and out.colors.shape == out.points.shape)
        return
    assert isinstance(out, np.ndarray) and out.size > 0, name
    if name == "j.png":
        assert out.dtype in (np.uint8, np.uint16) and (out.ndim == 2 or (out.ndim == 3 and out.shape[2] in (3, 4)))
    elif name == "j.pfm":
        assert out.dtype == np.float32 and (out.ndim == 2 or (out.ndim == 3 and out.shape[2] == 3))
        assert out.nbytes <= n_bytes  # the raster is stored uncompressed
    else:  # disparity maps
        assert out.dtype == np.float32 and out.ndim == 2
        assert not np.isinf(out).any() and not (out < 0).any()


@pytest.mark.parametrize(
    "reader",
    [read_image, read_pfm, read_ply, read_kitti_disparity, lambda p: read_scaled_disparity(p, 4)],
    ids=["image", "pfm", "ply", "kitti", "scaled"],
)
def test_every_reader_refuses_missing_empty_and_directories(tmp_path: Path, reader) -> None:  # noqa: ANN001
    with pytest.raises(FileNotFoundError, match="missing.bin"):
        reader(tmp_path / "missing.bin")
    folder = tmp_path / "folder.png"
    folder.mkdir()
    with pytest.raises(FileNotFoundError, match="directory"):
        reader(folder)
    (tmp_path / "empty.bin").write_bytes(b"")
    with pytest.raises(FileFormatError, match="empty"):
        reader(tmp_path / "empty.bin")
