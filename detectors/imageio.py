"""Reading an image file for the detectors CLI and benchmark, on any path.

``cv2.imread`` returns None on a missing file and on non-ASCII paths on Windows, which then reads as
"not an image"; :func:`read_image` decodes the bytes with ``cv2.imdecode`` and fails with a clear error.
(``detectors`` is a leaf package and does not import ``stereo_classic.io``.)
"""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np

__all__ = ["read_image"]


def read_image(path: str | os.PathLike, flags: int = cv2.IMREAD_COLOR) -> np.ndarray:
    """The image at ``path`` as ``cv2.imread`` would give it (BGR uint8 by default), for any path.

    Raises ``FileNotFoundError`` when ``path`` is not a file and ``ValueError`` when it cannot be decoded,
    both naming the path.
    """
    p = Path(os.fspath(path))
    if not p.is_file():
        raise FileNotFoundError(f"image not found: {p}")
    image = cv2.imdecode(np.fromfile(p, np.uint8), flags)
    if image is None:
        raise ValueError(f"image {p} could not be decoded (not an image or corrupt)")
    return image
