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
