"""Images: read any format OpenCV decodes (never None), write atomically by extension.

Example
-------
>>> import numpy as np, tempfile, pathlib
>>> from stereo_classic.io import read_image, write_image
>>> path = pathlib.Path(tempfile.mkdtemp()) / "grey.png"
>>> write_image(path, np.full((2, 3), 7, np.uint8))
>>> image = read_image(path)
>>> image.shape, image.dtype, int(image[1, 2, 0])
((2, 3, 3), dtype('uint8'), 7)
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import struct
import sys
import tempfile
from collections.abc import Iterator
from typing import Any

import cv2
import numpy as np

from stereo_classic.io._common import PathLike, as_path, encode_image, existing_file
from stereo_classic.io.atomic import atomic_write
from stereo_classic.io.errors import FileFormatError

__all__ = ["header_size", "read_image", "write_image"]

log = logging.getLogger("stereo_classic.io")

#: OpenCV refuses to decode images with more pixels than this (``OPENCV_IO_MAX_IMAGE_PIXELS``, default 2^30)
#: or wider / taller than 2^20 px.
MAX_IMAGE_PIXELS = int(os.environ.get("OPENCV_IO_MAX_IMAGE_PIXELS") or 1 << 30)
MAX_IMAGE_SIDE = 1 << 20


def header_size(data: np.ndarray | bytes) -> tuple[int, int] | None:
    """(width, height) read from a PNG, JPEG, BMP or GIF header without decoding the pixels; None otherwise.

    >>> header_size(b"GIF89a" + bytes([3, 0, 2, 0]))
    (3, 2)
    """
    b = bytes(data[:1 << 16])
    if b[:8] == b"\x89PNG\r\n\x1a\n" and len(b) >= 24 and b[12:16] == b"IHDR":
        return struct.unpack(">II", b[16:24])
    if b[:2] == b"BM" and len(b) >= 26:
        w, h = struct.unpack("<ii", b[18:26])
        return abs(w), abs(h)
    if b[:6] in (b"GIF87a", b"GIF89a") and len(b) >= 10:
        return struct.unpack("<HH", b[6:10])
    if b[:2] == b"\xff\xd8":  # JPEG: walk the segments to the first start-of-frame
        i = 2
        while i + 9 < len(b):
            if b[i] != 0xFF:
                return None
            marker = b[i + 1]
            if marker in (0xD8, 0x01) or 0xD0 <= marker <= 0xD7:
                i += 2
                continue
            length = struct.unpack(">H", b[i + 2:i + 4])[0]
            if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
                h, w = struct.unpack(">HH", b[i + 5:i + 9])
                return w, h
            i += 2 + length
    return None


def _truncated(data: np.ndarray | bytes) -> str:
    """Why a PNG or JPEG that did not decode looks cut short, from its own structure; "" when it does not.

    Decoders do not always say so themselves (OpenCV 5.1's PNG reader fails a truncated file silently).

    >>> _truncated(b"\\x89PNG\\r\\n\\x1a\\n" + bytes(20))
    '; the file ends before its IEND chunk: it is truncated'
    """
    tail = bytes(data[-64:])
    head = bytes(data[:8])
    if head == b"\x89PNG\r\n\x1a\n" and b"IEND" not in tail:
        return "; the file ends before its IEND chunk: it is truncated"
    if head[:2] == b"\xff\xd8" and b"\xff\xd9" not in tail:
        return "; the file ends before its end-of-image marker: it is truncated"
    return ""


def _too_large(width: int, height: int) -> bool:
    return width * height > MAX_IMAGE_PIXELS or width > MAX_IMAGE_SIDE or height > MAX_IMAGE_SIDE


def _too_large_message(p: Any, width: int, height: int) -> str:
    size = f"{width} x {height} = {width * height} pixels, " if width and height else ""
    return (f"image {p} is too large to decode ({size}OpenCV decodes at most {MAX_IMAGE_PIXELS} pixels and "
            f"{MAX_IMAGE_SIDE} px a side; the variable OPENCV_IO_MAX_IMAGE_PIXELS raises the pixel limit)")


@contextlib.contextmanager
def _native_stderr_captured(lines: list[str]) -> Iterator[None]:
    """Hold what native code (libpng, OpenCV's log) writes to file descriptor 2 while decoding, into ``lines``.

    libpng prints "libpng error: ..." straight to the terminal before OpenCV returns; the caller puts it into
    its own message instead. Anything else written to stderr meanwhile is passed on afterwards.
    """
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):  # no real stderr (embedded interpreters): decode as is
        yield
        return
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            text = tmp.read().decode("utf-8", "replace")
    other = []
    for line in text.splitlines():
        if line.startswith(("libpng", "[ WARN", "[ERROR", "[ INFO")) or "grfmt_" in line:
            lines.append(re.sub(r"^(\[[^]]*\]\s*)?(global \S+:\d+ \S+ )?", "", line).strip())
        elif line.strip():
            other.append(line)
    if other:
        sys.stderr.write("\n".join(other) + "\n")


def read_image(path: PathLike, *, grayscale: bool = False) -> np.ndarray:
    """Read an image file (PNG, JPEG, PGM/PPM, BMP, TIFF, ...).

    Unlike ``cv2.imread`` it never returns None, and it reads paths with any characters (it decodes
    the bytes with ``cv2.imdecode``).

    Parameters
    ----------
    path : str or os.PathLike
    grayscale : bool, keyword-only
        False (default): (H, W, 3) BGR, grey files are expanded to three equal channels, alpha is
        dropped. True: (H, W), colour files are converted to grey.

    Returns
    -------
    image : (H, W, 3) or (H, W) uint8, or uint16 when the file stores 16 bits.

    Raises
    ------
    FileNotFoundError
        The file does not exist or is a directory.
    FileFormatError
        Empty, truncated or not an image OpenCV can decode (the decoder's own complaint, e.g. libpng's, is in
        the message instead of on the terminal), or too large to decode (the message gives its size).
    """
    p = existing_file(path, "image")
    data = np.fromfile(p, dtype=np.uint8)
    flags = cv2.IMREAD_ANYDEPTH | (cv2.IMREAD_GRAYSCALE if grayscale else cv2.IMREAD_COLOR)
    size = header_size(data)
    if size is not None and _too_large(*size):
        raise FileFormatError(_too_large_message(p, *size))
    noise: list[str] = []
    try:
        with _native_stderr_captured(noise):
            image = cv2.imdecode(data, flags)
    except cv2.error as exc:
        if "validateInputImageSize" in str(exc):  # OpenCV's own size check: say so, with the size when known
            raise FileFormatError(_too_large_message(p, *(size or (0, 0)))) from None
        noise.append(str(exc).strip().splitlines()[-1])
        image = None
    if image is None or image.size == 0:
        said = f"; the decoder said: {'; '.join(noise)}" if noise else ""
        raise FileFormatError(
            f"cannot decode image {p} ({data.size} bytes): not an image format OpenCV reads, or the "
            f"file is truncated or corrupt{_truncated(data)}{said}"
        )
    for line in noise:  # a decoded image with warnings (an odd colour profile, ...): for -vv only
        log.debug("%s: %s", p, line)
    if image.dtype not in (np.uint8, np.uint16):
        raise FileFormatError(
            f"image {p} has pixel type {image.dtype}; expected 8- or 16-bit (use read_pfm for float maps)"
        )
    return image


def _check_image_array(image: Any, name: str = "image") -> np.ndarray:
    if not isinstance(image, np.ndarray):
        raise TypeError(f"`{name}` must be a numpy array, got {type(image).__name__}")
    if image.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"`{name}` must have dtype uint8 or uint16, got {image.dtype}")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (3, 4))):
        raise ValueError(f"`{name}` must have shape (H, W), (H, W, 3) or (H, W, 4), got {image.shape}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"`{name}` must not be empty, got shape {image.shape}")
    return image


def write_image(path: PathLike, image: np.ndarray, *, params: list[int] | tuple[int, ...] = ()) -> None:
    """Write an image atomically; the format comes from the file extension (``.png``, ``.jpg``, ...).

    Parameters
    ----------
    path : str or os.PathLike
    image : (H, W), (H, W, 3) BGR or (H, W, 4) BGRA, uint8 or uint16
    params : OpenCV ``imwrite`` flags, e.g. ``(cv2.IMWRITE_JPEG_QUALITY, 95)``.
    """
    p = as_path(path)
    image = _check_image_array(image)
    data = encode_image(p, np.ascontiguousarray(image), params)
    with atomic_write(p, "wb") as f:
        f.write(data)
