"""stereo_classic.io.images: round trips, 16-bit and grey images, odd paths, hostile files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from stereo_classic.io import FileFormatError, read_image, write_image


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


def _png_header_only(width: int, height: int) -> bytes:
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64)) + chunk(b"IEND", b"")


def test_image_too_large_to_decode_says_so_with_its_size(tmp_path: Path, capfd) -> None:
    path = tmp_path / "huge.png"
    path.write_bytes(_png_header_only(40000, 40000))
    with pytest.raises(FileFormatError, match=r"too large to decode \(40000 x 40000 = 1600000000 pixels"):
        read_image(path)
    path.write_bytes(_png_header_only(2_000_000, 1))  # few pixels, but wider than OpenCV decodes
    with pytest.raises(FileFormatError, match="too large to decode"):
        read_image(path)
    assert capfd.readouterr().err == ""


def test_decoder_noise_goes_into_the_message_not_the_terminal(tmp_path: Path, capfd) -> None:
    rng = np.random.default_rng(0)
    write_image(tmp_path / "ok.png", rng.integers(0, 256, (40, 50, 3), dtype=np.uint8))
    good = (tmp_path / "ok.png").read_bytes()
    broken = bytearray(good)
    broken[100:120] = b"\xff" * 20  # inside the compressed pixels: libpng complains on stderr by itself
    (tmp_path / "crc.png").write_bytes(bytes(broken))
    (tmp_path / "short.png").write_bytes(good[: len(good) // 2])
    with pytest.raises(FileFormatError, match="cannot decode image .*crc.png.*the decoder said: .+") as crc:
        read_image(tmp_path / "crc.png")
    assert "truncated" not in str(crc.value).split("corrupt", 1)[1]  # complete file: no truncation claimed
    # the truncated file is told as such from its own structure, whether or not the decoder said anything
    # (up to OpenCV 5.0 libpng complained on stderr; OpenCV 5.1 fails silently)
    with pytest.raises(FileFormatError, match="cannot decode image .*short.png.*ends before its IEND chunk"):
        read_image(tmp_path / "short.png")
    jpeg = tmp_path / "ok.jpg"
    write_image(jpeg, rng.integers(0, 256, (40, 50, 3), dtype=np.uint8))
    (tmp_path / "short.jpg").write_bytes(jpeg.read_bytes()[:200])
    with pytest.raises(FileFormatError, match="short.jpg.*ends before its end-of-image marker"):
        read_image(tmp_path / "short.jpg")
    assert capfd.readouterr().err == ""  # nothing reached the terminal before the error


def test_header_size_of_the_common_formats(tmp_path: Path) -> None:
    from stereo_classic.io.images import header_size

    img = np.zeros((17, 29, 3), np.uint8)
    for ext in (".png", ".jpg", ".bmp"):
        write_image(tmp_path / f"a{ext}", img)
        assert header_size((tmp_path / f"a{ext}").read_bytes()) == (29, 17), ext
    assert header_size(b"not an image") is None and header_size(b"") is None
