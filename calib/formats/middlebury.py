"""Middlebury 2014/2021 ``calib.txt``: ``cam0``, ``cam1``, ``doffs``, ``baseline`` (millimetres), ``width``, ``height``.

The millimetre baseline becomes metres here and nowhere else. Readers return plain values;
``RectifiedRig.from_middlebury`` builds the rig.
"""

from __future__ import annotations

import logging
import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from calib.errors import CalibrationError
from calib.formats._common import PathLike, finite, read_text
from calib.geometry import check_image_size

__all__ = ["read_middlebury_calib", "read_rectified"]

log = logging.getLogger(__name__)

_MATRIX_RE = re.compile(r"^\[(.*)\]$")


def read_middlebury_calib(path: PathLike) -> dict[str, Any]:
    """All ``key=value`` entries of a Middlebury 2014 ``calib.txt``, as stored.

    Returns
    -------
    dict
        ``cam0``/``cam1`` as (3, 3) float64 arrays, every other value as a float (``baseline`` still in
        millimetres, ``ndisp``/``width``/``height``/``vmin``/``vmax`` as numbers).
    """
    path, text = read_text(path, "Middlebury calib.txt")
    out: dict[str, Any] = {}
    for line_no, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        key, sep, value = line.partition("=")
        key, value = key.strip(), value.strip()
        if not sep or not key:
            raise CalibrationError(f"{path}: line {line_no} is not `key=value`: {line[:60]!r}")
        match = _MATRIX_RE.match(value)
        rows = [r.split() for r in match.group(1).split(";")] if match else []
        if match and (len(rows) != 3 or any(len(r) != 3 for r in rows)):
            raise CalibrationError(f"{path}: key `{key}` must be a 3x3 matrix [a b c; d e f; g h i], got {value!r}")
        try:
            if match:
                out[key] = np.array([[float(v) for v in r] for r in rows], dtype=np.float64)
            else:
                out[key] = float(value)
        except ValueError:
            raise CalibrationError(f"{path}: key `{key}` must hold numbers, got {value!r}") from None
    return out


def read_rectified(calib_txt: PathLike, *, image_size: tuple[int, int] | None = None) -> dict[str, Any]:
    """The rectified geometry of a Middlebury ``calib.txt``, ``baseline`` converted from mm to metres.

    Parameters
    ----------
    calib_txt : str or os.PathLike
    image_size : (width, height) or None
        Size of the images. When it differs from the file's ``width``/``height`` with the same aspect ratio
        (a full-size ``calib.txt`` beside quarter-size images), the geometry is scaled as ``cv2.resize``
        scales the images; another aspect ratio is refused.

    Returns
    -------
    dict
        ``focal_px``, ``cx_left``, ``cx_right``, ``cy`` (pixels), ``baseline_m`` (metres), ``image_size``.

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as tmp:
    ...     path = Path(tmp) / "calib.txt"
    ...     _ = path.write_text("cam0=[700 0 320; 0 700 240; 0 0 1]\\ncam1=[700 0 330; 0 700 240; 0 0 1]\\n"
    ...                         "doffs=10\\nbaseline=100\\nwidth=640\\nheight=480\\n")
    ...     read_rectified(path, image_size=(320, 240))
    {'focal_px': 350.0, 'cx_left': 159.75, 'cx_right': 164.75, 'cy': 119.75, 'baseline_m': 0.1, 'image_size': (320, 240)}
    """
    values = read_middlebury_calib(calib_txt)
    path = Path(calib_txt)

    def need(key: str) -> Any:
        if key not in values:
            raise CalibrationError(f"{path}: missing key `{key}`")
        return values[key]

    cam0, cam1 = need("cam0"), need("cam1")
    for key, cam in (("cam0", cam0), ("cam1", cam1)):
        if not isinstance(cam, np.ndarray):
            raise CalibrationError(f"{path}: key `{key}` must be a 3x3 matrix [a b c; d e f; g h i]")
        finite(path, key, cam)
    baseline_mm = need("baseline")
    if isinstance(baseline_mm, np.ndarray) or not (math.isfinite(baseline_mm) and baseline_mm > 0):
        raise CalibrationError(f"{path}: key `baseline` must be a positive number of millimetres, got {baseline_mm!r}")
    if "doffs" in values:
        doffs = values["doffs"]
        if isinstance(doffs, np.ndarray) or not math.isfinite(doffs):
            raise CalibrationError(f"{path}: key `doffs` must be a finite number, got {doffs!r}")
        if abs((cam1[0, 2] - cam0[0, 2]) - doffs) > 1e-2:
            log.warning("%s: doffs=%g differs from cam1 cx - cam0 cx = %g; using doffs", path, doffs, cam1[0, 2] - cam0[0, 2])
    else:
        doffs = cam1[0, 2] - cam0[0, 2]
    file_size = None
    if image_size is None or "width" in values or "height" in values:
        width, height = need("width"), need("height")
        if isinstance(width, np.ndarray) or isinstance(height, np.ndarray) or not (
            float(width).is_integer() and float(height).is_integer() and width > 0 and height > 0
        ):
            raise CalibrationError(f"{path}: keys `width`/`height` must be positive integers, got {width!r}/{height!r}")
        file_size = (int(width), int(height))
    size = file_size if image_size is None else check_image_size("image_size", image_size)
    factor = 1.0
    if file_size is not None and size != file_size:
        # calib.txt of another resolution (e.g. full-size calib.txt beside quarter-size images): scale the
        # rig when the aspect ratio agrees to within a pixel of rounding, refuse otherwise
        factor = size[0] / file_size[0]
        if abs(file_size[1] * factor - size[1]) > 1.0:
            raise CalibrationError(
                f"{path}: calib.txt is for {file_size[0]}x{file_size[1]} images but the images are "
                f"{size[0]}x{size[1]}, a different aspect ratio; use the calib.txt of these images"
            )
        log.info("%s: calib.txt is for %dx%d images, the images are %dx%d: scaling the rig by %g",
                 path, file_size[0], file_size[1], size[0], size[1], factor)

    def px(c: float) -> float:  # pixel-centre convention, as RectifiedRig.scaled and cv2.resize
        return (c + 0.5) * factor - 0.5 if factor != 1.0 else c

    return {"focal_px": float(cam0[0, 0]) * factor, "cx_left": float(px(cam0[0, 2])),
            "cx_right": float(px(cam0[0, 2] + doffs)), "cy": float(px(cam0[1, 2])),
            "baseline_m": float(baseline_mm) / 1000.0, "image_size": size}
