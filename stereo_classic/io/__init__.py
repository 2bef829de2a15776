"""File input and output: images, PFM, KITTI and Middlebury disparity maps, KITTI depth maps, PLY point clouds.

Every reader checks its file before it allocates anything and raises ``FileNotFoundError`` (missing
file, or a directory where a file was expected) or :class:`FileFormatError` (a ``ValueError``: empty,
truncated, lying or unsupported file) with the path in the message. Every writer is atomic
(:func:`atomic_write`): a failed write never leaves a half-written file behind.

Inside the project disparity is float32 pixels and depth float32 metres, with NaN for unknown; the
scale factors of the file formats (KITTI x256, Middlebury x4/x8/x16, PFM ``inf``) exist only in this
package.

=====================  =========================================================================
module                 what it reads and writes
=====================  =========================================================================
``atomic``             :func:`atomic_write`
``images``             :func:`read_image`, :func:`write_image` (any format OpenCV handles)
``pfm``                :func:`read_pfm`, :func:`write_pfm` (Middlebury float maps)
``disparity_png``      KITTI disparity and depth PNGs (x256), Middlebury scaled disparity maps
``ply``                :class:`PointCloud`, :func:`read_ply`, :func:`write_ply`
``errors``             :class:`FileFormatError`
=====================  =========================================================================

Example
-------
>>> import numpy as np, tempfile, pathlib
>>> from stereo_classic.io import write_pfm, read_pfm
>>> path = pathlib.Path(tempfile.mkdtemp()) / "d.pfm"
>>> write_pfm(path, np.arange(6, dtype=np.float32).reshape(2, 3))
>>> float(read_pfm(path)[1, 2])
5.0
"""

from __future__ import annotations

from stereo_classic.io.atomic import atomic_write
from stereo_classic.io.disparity_png import (
    read_kitti_depth,
    read_kitti_disparity,
    read_scaled_disparity,
    write_kitti_depth,
    write_kitti_disparity,
    write_scaled_disparity,
)
from stereo_classic.io.errors import FileFormatError
from stereo_classic.io.images import read_image, write_image
from stereo_classic.io.pfm import read_pfm, write_pfm
from stereo_classic.io.ply import PointCloud, read_ply, write_ply

__all__ = [
    "FileFormatError",
    "PointCloud",
    "atomic_write",
    "read_image",
    "write_image",
    "read_pfm",
    "write_pfm",
    "read_kitti_disparity",
    "write_kitti_disparity",
    "read_kitti_depth",
    "write_kitti_depth",
    "read_scaled_disparity",
    "write_scaled_disparity",
    "read_ply",
    "write_ply",
]
