"""What the format readers and writers share: reading text, writing it atomically, checking values.

Plain functions on paths, strings and numpy arrays; they know nothing of the rig classes.
"""

from __future__ import annotations

import logging
import os
import secrets
from pathlib import Path
from typing import Any

import numpy as np

from calib.errors import CalibrationError

__all__ = ["PathLike", "read_text", "atomic_write_text", "finite", "rectified_from_projections"]

log = logging.getLogger(__name__)

#: What every reader and writer accepts as a file name.
PathLike = str | os.PathLike[str]


def read_text(path: PathLike, what: str) -> tuple[Path, str]:
    """The UTF-8 text of a calibration file.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    what : str
        What the file should be ("KITTI calibration", ...), for the messages.

    Returns
    -------
    path : Path
    text : str

    Raises
    ------
    FileNotFoundError
        The file does not exist.
    CalibrationError
        Not a regular file, empty (or only whitespace), or not UTF-8.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"{what} file not found: {path}")
    if not path.is_file():
        raise CalibrationError(f"{what} file {path} is not a regular file")
    data = path.read_bytes()
    if not data.strip():
        raise CalibrationError(f"{what} file {path} is empty")
    try:
        return path, data.decode("utf-8")
    except UnicodeDecodeError:
        raise CalibrationError(f"{what} file {path} is not UTF-8 text (binary or corrupt file?)") from None


def atomic_write_text(path: PathLike, text: str) -> None:
    """Write ``text`` (UTF-8, ``\\n``) so that ``path`` appears complete or not at all.

    Same behaviour as ``stereo_classic.io.atomic_write`` (calib is a leaf package and must not import
    stereo_classic): a temporary file in the same folder created with mode 0o666 so that the umask decides
    the permissions, flushed and fsynced, renamed over ``path``, removed if anything fails.

    Raises
    ------
    FileNotFoundError
        The folder of ``path`` does not exist.
    CalibrationError
        ``path`` is a directory.
    """
    path = Path(path)
    if path.is_dir():
        raise CalibrationError(f"output path {path} is a directory")
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise FileNotFoundError(f"output folder does not exist: {parent}")
    tmp = parent / f".{path.name}.{secrets.token_hex(6)}.tmp"
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        handle = os.fdopen(fd, "w", encoding="utf-8", newline="\n")
    except BaseException:
        os.close(fd)
        tmp.unlink(missing_ok=True)
        raise
    try:
        with handle:
            handle.write(text)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def finite(path: Path, key: str, value: np.ndarray) -> np.ndarray:
    """``value`` unchanged when all of it is finite, else CalibrationError naming ``path`` and ``key``."""
    if not np.all(np.isfinite(value)):
        raise CalibrationError(f"{path}: key `{key}` must be finite, got {np.asarray(value).tolist()}")
    return value


def rectified_from_projections(path: Path, p1: np.ndarray, p2: np.ndarray, size: tuple[int, int],
                               names: tuple[str, str]) -> dict[str, Any]:
    """The rectified geometry of two 3x4 projection matrices (OpenCV ``P1``/``P2``, KITTI ``P2``/``P3``).

    Parameters
    ----------
    path : Path
        The file they come from, for the messages.
    p1, p2 : (3, 4) float64
        Projections of the rectified left and right cameras, pixels; ``p2[0, 3] = -f * baseline``.
    size : (width, height)
        Size of the rectified images.
    names : (str, str)
        The keys of ``p1`` and ``p2`` in the file, for the messages.

    Returns
    -------
    dict
        ``focal_px``, ``cx_left``, ``cx_right``, ``cy`` (floats, pixels), ``baseline_m`` (float, metres)
        and ``image_size``: the arguments of ``RectifiedRig``.

    Raises
    ------
    CalibrationError
        Focal length not > 0, different focal lengths or ``cy``, or a baseline that is not > 0.

    Examples
    --------
    >>> p1 = np.array([[700.0, 0, 320, 0], [0, 700, 240, 0], [0, 0, 1, 0]])
    >>> p2 = p1.copy(); p2[0, 3] = -70.0
    >>> rectified_from_projections(Path("rig.yaml"), p1, p2, (640, 480), ("P1", "P2"))["baseline_m"]
    0.1
    """
    n1, n2 = names
    f = p1[0, 0]
    if not f > 0:
        raise CalibrationError(f"{path}: `{n1}`[0,0] (focal length) must be > 0, got {f}")
    if abs(p2[0, 0] - f) > 1e-6 * f or abs(p1[1, 1] - p2[1, 1]) > 1e-6 * f:
        raise CalibrationError(f"{path}: `{n1}` and `{n2}` have different focal lengths: not a rectified pair")
    if abs(p1[1, 2] - p2[1, 2]) > 1e-3:
        raise CalibrationError(f"{path}: `{n1}` and `{n2}` have different cy ({p1[1, 2]} vs {p2[1, 2]}): not a horizontal rectified pair")
    if abs(p1[1, 1] - f) > 1e-3 * f:
        log.info("%s: fx=%.6g and fy=%.6g differ; using fx", path, f, p1[1, 1])
    baseline = (p1[0, 3] - p2[0, 3]) / f
    if not baseline > 0:
        raise CalibrationError(
            f"{path}: baseline from `{n1}`/`{n2}` is {baseline:.6g} m (must be > 0): is `{n2}` really the right camera?"
        )
    return {"focal_px": float(f), "cx_left": float(p1[0, 2]), "cx_right": float(p2[0, 2]), "cy": float(p1[1, 2]),
            "baseline_m": float(baseline), "image_size": size}
