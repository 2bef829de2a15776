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

from typing import Any

import cv2
import numpy as np

from stereo_classic.io._common import PathLike, as_path, encode_image, existing_file
from stereo_classic.io.atomic import atomic_write
from stereo_classic.io.errors import FileFormatError

__all__ = ["read_image", "write_image"]


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
        Empty, truncated or not an image OpenCV can decode.
    """
    p = existing_file(path, "image")
    data = np.fromfile(p, dtype=np.uint8)
    flags = cv2.IMREAD_ANYDEPTH | (cv2.IMREAD_GRAYSCALE if grayscale else cv2.IMREAD_COLOR)
    try:
        image = cv2.imdecode(data, flags)
    except cv2.error:
        image = None
    if image is None or image.size == 0:
        raise FileFormatError(
            f"cannot decode image {p} ({data.size} bytes): not an image format OpenCV reads, or the "
            "file is truncated or corrupt"
        )
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
