"""Checks and codecs shared by the readers and writers of :mod:`stereo_classic.io` (private).

Example
-------
>>> from stereo_classic.io._common import as_path
>>> as_path("a/b.png").name
'b.png'
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from stereo_classic.io.errors import FileFormatError

__all__ = ["PathLike", "as_path", "as_real_array", "encode_image", "existing_file", "read_single_channel"]

PathLike = str | os.PathLike


def as_path(path: Any, name: str = "path") -> Path:
    """``path`` as a :class:`~pathlib.Path`; ``TypeError``/``ValueError`` naming ``name`` otherwise."""
    if isinstance(path, (str, os.PathLike)):
        text = os.fspath(path)
        if isinstance(text, bytes):
            text = os.fsdecode(text)
        if text == "":
            raise ValueError(f"`{name}` must be a non-empty file path, got ''")
        return Path(text)
    raise TypeError(f"`{name}` must be a str or os.PathLike file path, got {type(path).__name__}")


def existing_file(path: Any, what: str) -> Path:
    """Return ``path`` as a Path after checking that it is a non-empty regular file."""
    p = as_path(path)
    if not p.exists():
        raise FileNotFoundError(f"{what} file not found: {p}")
    if p.is_dir():
        raise FileNotFoundError(f"{what}: expected a file, got a directory: {p}")
    size = p.stat().st_size
    if size == 0:
        raise FileFormatError(f"{what} file is empty (0 bytes): {p}")
    return p


def as_real_array(values: Any, name: str) -> np.ndarray:
    """``values`` itself after checking that it is a real (integer or floating, not bool) numpy array."""
    if not isinstance(values, np.ndarray):
        raise TypeError(f"`{name}` must be a numpy array, got {type(values).__name__}")
    if values.dtype == bool or not (np.issubdtype(values.dtype, np.integer) or np.issubdtype(values.dtype, np.floating)):
        raise ValueError(f"`{name}` must be a real integer or floating array, got dtype {values.dtype}")
    return values


def encode_image(path: Path, image: np.ndarray, params: list[int] | tuple[int, ...] = ()) -> bytes:
    """Encode ``image`` in the format that the extension of ``path`` names (OpenCV ``imencode``)."""
    ext = path.suffix.lower()
    if not ext:
        raise ValueError(f"cannot tell the image format of {path}: the file name has no extension")
    try:
        ok, buf = cv2.imencode(ext, image, list(params))
    except cv2.error as exc:
        raise ValueError(f"OpenCV cannot write {image.dtype} {image.shape} images as {ext!r} ({path}): {exc}") from exc
    if not ok:
        raise ValueError(f"OpenCV cannot write {image.dtype} {image.shape} images as {ext!r} ({path})")
    return buf.tobytes()


def read_single_channel(path: PathLike, what: str) -> tuple[Path, np.ndarray]:
    """Decode a single-channel image file unchanged (8 or 16 bit); grey saved as three equal channels is accepted."""
    p = existing_file(path, what)
    data = np.fromfile(p, dtype=np.uint8)
    try:
        image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    except cv2.error:
        image = None
    if image is None or image.size == 0:
        raise FileFormatError(f"cannot decode {what} {p}: not a PNG/PGM OpenCV reads, or truncated/corrupt")
    if image.ndim == 3:
        # some tools save grey maps as RGB with three equal channels: accept those only
        if image.shape[2] >= 3 and np.array_equal(image[:, :, 0], image[:, :, 1]) and np.array_equal(
            image[:, :, 0], image[:, :, 2]
        ):
            image = np.ascontiguousarray(image[:, :, 0])
        else:
            raise FileFormatError(f"{what} {p} must be a single-channel image, got {image.shape[2]} channels")
    return p, image
