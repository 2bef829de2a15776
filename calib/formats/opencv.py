"""OpenCV FileStorage calibration files (YAML, either ``%YAML`` header, or XML): read and write plain values.

Readers return dicts of float64 numpy arrays, floats and ``(width, height)`` tuples, named as the arguments
of ``StereoRig`` / ``RectifiedRig``, which build themselves from them (``StereoRig.from_opencv_yaml``).
Every reader raises ``FileNotFoundError`` for a missing file and :class:`CalibrationError` (a ``ValueError``)
naming the file and the key for anything else: empty file, missing key, non-numeric value, wrong shape.
"""

from __future__ import annotations

import math
import re
from typing import Any

import cv2
import numpy as np

from calib.errors import CalibrationError
from calib.formats._common import PathLike, atomic_write_text, finite, read_text, rectified_from_projections
from calib.geometry import check_image_size

__all__ = [
    "OpenCVStorage",
    "read_keys",
    "read_stereo",
    "read_rectified",
    "read_projections",
    "read_rectify_maps",
    "write_stereo",
    "write_rectified",
]

_HEADER_RE = re.compile(r"\A\s*%YAML[: ]\s*1\.\d+[^\n]*\n")


def _storage_variants(text: str) -> list[str]:
    """The text as is, then with the other ``%YAML`` header spelling, then without a header."""
    if text.lstrip().startswith("<"):
        return [text]
    body = _HEADER_RE.sub("", text, count=1)
    variants = [text, "%YAML:1.0\n" + body, "%YAML 1.2\n" + body, body]
    out: list[str] = []
    for v in variants:
        if v not in out:
            out.append(v)
    return out


class OpenCVStorage:
    """A ``cv2.FileStorage`` opened from a file (YAML, either header, or XML) with checked accessors.

    Parameters
    ----------
    path : str or os.PathLike
        The file.
    what : str
        What the file should be, for the messages ("OpenCV calibration", "ROS camera_info", ...).

    Attributes
    ----------
    path : Path
    keys : tuple of str
        The keys at the top level, in file order (never empty).
    """

    def __init__(self, path: PathLike, what: str = "calibration") -> None:
        self.path, text = read_text(path, what)
        errors = []
        self.fs = None
        for variant in _storage_variants(text):
            try:
                fs = cv2.FileStorage(variant, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
            except (cv2.error, SystemError) as exc:  # cv2 raises SystemError on some parse errors
                last = str(exc).strip().splitlines()[-1] if str(exc).strip() else ""
                # keep OpenCV's parser message ("Parsing error ... line 3"), not Python binding noise
                errors.append(last if isinstance(exc, cv2.error) and last else "a parse error")
                continue
            if fs.isOpened():
                self.fs = fs
                break
        if self.fs is None:
            raise CalibrationError(f"{self.path}: not a readable OpenCV FileStorage YAML/XML file ({errors[-1] if errors else 'cannot open'})")
        try:
            root = self.fs.root()
            self.keys = tuple(root.keys()) if root.isMap() else ()
        except cv2.error:
            self.keys = ()
        if not self.keys:
            raise CalibrationError(f"{self.path}: no key-value mapping at the top level (empty or not a calibration file)")

    def has(self, key: str) -> bool:
        """True when ``key`` is at the top level."""
        return key in self.keys

    def first(self, *keys: str) -> str | None:
        """The first of ``keys`` present at the top level, or None."""
        return next((k for k in keys if k in self.keys), None)

    def _node(self, key: str) -> Any:
        if key not in self.keys:
            raise CalibrationError(f"{self.path}: missing key `{key}`")
        return self.fs.getNode(key)

    def _numbers(self, key: str, node: Any) -> list[float]:
        values = []
        for i in range(node.size()):
            item = node.at(i)
            if not (item.isReal() or item.isInt()):
                raise CalibrationError(f"{self.path}: key `{key}` must hold numbers, found a non-numeric entry at index {i}")
            values.append(float(item.real()))
        return values

    def matrix(self, key: str, shape: tuple[int, ...] | None = None) -> np.ndarray:
        """The matrix under ``key`` (``!!opencv-matrix``, a ROS-style {rows, cols, data} map, or a flat list),
        float64, finite, of ``shape`` when given."""
        node = self._node(key)
        arr: np.ndarray | None = None
        if node.isMap() and "data" in node.keys():
            data = node.getNode("data")
            if not data.isSeq():
                raise CalibrationError(f"{self.path}: key `{key}`: `data` must be a list of numbers")
            flat = np.array(self._numbers(key, data), dtype=np.float64)
            rows, cols = node.getNode("rows"), node.getNode("cols")
            if rows.isInt() and cols.isInt():
                r, c = int(rows.real()), int(cols.real())
                if r * c != flat.size:
                    raise CalibrationError(f"{self.path}: key `{key}` says {r}x{c} but holds {flat.size} numbers")
                arr = flat.reshape(r, c)
            else:
                arr = flat
        elif node.isSeq():
            arr = np.array(self._numbers(key, node), dtype=np.float64)
        elif node.isReal() or node.isInt():
            arr = np.array([float(node.real())])
        else:
            raise CalibrationError(f"{self.path}: key `{key}` must be a matrix of numbers, got a {'string' if node.isString() else 'non-numeric node'}")
        arr = finite(self.path, key, np.asarray(arr, dtype=np.float64))
        if shape is not None:
            ok = arr.size == int(np.prod(shape))
            if ok and arr.ndim == 2:
                ok = arr.shape == shape if len(shape) == 2 else 1 in arr.shape
            if not ok:
                raise CalibrationError(f"{self.path}: key `{key}` must have shape {shape}, got {arr.shape}")
            arr = arr.reshape(shape)
        return arr

    def vector(self, key: str) -> np.ndarray:
        """The vector under ``key`` (a row, a column or a flat list), ``(n,) float64``."""
        arr = self.matrix(key)
        if arr.ndim == 2 and 1 not in arr.shape:
            raise CalibrationError(f"{self.path}: key `{key}` must be a vector, got shape {arr.shape}")
        return arr.reshape(-1)

    def number(self, key: str) -> float:
        """The finite number under ``key``."""
        node = self._node(key)
        if not (node.isReal() or node.isInt()):
            raise CalibrationError(f"{self.path}: key `{key}` must be a number")
        value = float(node.real())
        if not math.isfinite(value):
            raise CalibrationError(f"{self.path}: key `{key}` must be finite, got {value}")
        return value

    def string(self, key: str) -> str:
        """The string under ``key``."""
        node = self._node(key)
        if not node.isString():
            raise CalibrationError(f"{self.path}: key `{key}` must be a string")
        return node.string()

    def image_size(self, override: tuple[int, int] | None) -> tuple[int, int]:
        """``override`` (checked) when given, else ``image_width``/``image_height`` (or ``width``/``height``,
        ``image_size``, ``imageSize``, ``size``) of the file."""
        if override is not None:
            return check_image_size("image_size", override)
        for wkey, hkey in (("image_width", "image_height"), ("width", "height")):
            if self.has(wkey) and self.has(hkey):
                return self._size(f"{wkey}/{hkey}", (self.number(wkey), self.number(hkey)))
        key = self.first("image_size", "imageSize", "size")
        if key is not None:
            return self._size(key, tuple(self.vector(key)))
        raise CalibrationError(
            f"{self.path}: missing key `image_width`/`image_height` (or `image_size`): pass image_size=(width, height)"
        )

    def _size(self, key: str, values: tuple[float, ...]) -> tuple[int, int]:
        if len(values) != 2 or not all(float(v).is_integer() and v > 0 for v in values):
            raise CalibrationError(f"{self.path}: key `{key}` must be two positive integers (width, height), got {list(values)}")
        return int(values[0]), int(values[1])


def read_keys(path: PathLike) -> tuple[str, ...]:
    """The top-level keys of an OpenCV FileStorage file, in file order (what ``load_rig`` sniffs)."""
    return OpenCVStorage(path).keys


def read_stereo(path: PathLike, *, image_size: tuple[int, int] | None = None) -> dict[str, Any]:
    """The raw stereo calibration ``K1 D1 K2 D2 R T`` (``M1``/``M2`` also accepted) of an OpenCV YAML/XML.

    Parameters
    ----------
    path : str or os.PathLike
    image_size : (width, height) or None
        Used when given, else read from the file (``image_width``/``image_height``, ``image_size``, ...).

    Returns
    -------
    dict
        ``K_left``, ``K_right`` (3, 3) float64 pixels; ``dist_left``, ``dist_right`` (k,) float64;
        ``R`` (3, 3) float64; ``T`` (3,) float64 metres; ``image_size`` (width, height) ints.
    """
    st = OpenCVStorage(path, "OpenCV calibration")
    k1 = st.first("K1", "M1", "cameraMatrix1", "camera_matrix_left") or "K1"
    k2 = st.first("K2", "M2", "cameraMatrix2", "camera_matrix_right") or "K2"
    d1 = st.first("D1", "distCoeffs1", "dist_coeffs_left") or "D1"
    d2 = st.first("D2", "distCoeffs2", "dist_coeffs_right") or "D2"
    values = {
        "K_left": st.matrix(k1, (3, 3)),
        "dist_left": st.vector(d1),
        "K_right": st.matrix(k2, (3, 3)),
        "dist_right": st.vector(d2),
        "R": st.matrix("R", (3, 3)),
        "T": st.vector("T"),
    }
    values["image_size"] = st.image_size(image_size)
    return values


def read_projections(path: PathLike, *, image_size: tuple[int, int] | None = None) -> dict[str, Any]:
    """The rectified geometry of the ``P1`` and ``P2`` (3x4) of an OpenCV YAML/XML; both are required.

    Returns
    -------
    dict
        ``focal_px``, ``cx_left``, ``cx_right``, ``cy`` (pixels), ``baseline_m`` (metres), ``image_size``.
    """
    st = OpenCVStorage(path, "OpenCV calibration")
    return _projections(st, st.image_size(image_size))


def _projections(st: OpenCVStorage, size: tuple[int, int]) -> dict[str, Any]:
    """The rectified geometry of the storage's ``P1`` and ``P2``."""
    return rectified_from_projections(st.path, st.matrix("P1", (3, 4)), st.matrix("P2", (3, 4)), size, ("P1", "P2"))


def read_rectified(path: PathLike, *, image_size: tuple[int, int] | None = None) -> dict[str, Any]:
    """The rectified geometry of an OpenCV YAML/XML with ``P1`` and ``P2`` (3x4), or else ``Q`` (4x4).

    Returns
    -------
    dict
        ``focal_px``, ``cx_left``, ``cx_right``, ``cy`` (pixels), ``baseline_m`` (metres), ``image_size``.
    """
    st = OpenCVStorage(path, "OpenCV calibration")
    size = st.image_size(image_size)
    if st.has("P1") and st.has("P2"):
        return _projections(st, size)
    if st.has("Q"):
        q = st.matrix("Q", (4, 4))
        if not (q[3, 2] > 0 and q[2, 3] > 0):
            raise CalibrationError(f"{st.path}: key `Q` must have Q[2,3] = f > 0 and Q[3,2] = 1/baseline > 0, got {q.tolist()}")
        baseline = 1.0 / q[3, 2]
        return {"focal_px": float(q[2, 3]), "cx_left": float(-q[0, 3]), "cx_right": float(-q[0, 3] + q[3, 3] * baseline),
                "cy": float(-q[1, 3]), "baseline_m": float(baseline), "image_size": size}
    raise CalibrationError(f"{st.path}: missing key `P1`/`P2` (or `Q`): needed for a rectified rig")


def read_rectify_maps(path: PathLike, *, image_size: tuple[int, int]) -> dict[str, Any]:
    """The undistort/rectify maps of the rectification an OpenCV YAML/XML holds (``K1 D1 K2 D2 R1 R2 P1 P2``).

    Parameters
    ----------
    path : str or os.PathLike
    image_size : (width, height)
        Size of the raw images (and of the rectified ones).

    Returns
    -------
    dict
        ``maps_left``, ``maps_right``: ``cv2.initUndistortRectifyMap`` outputs (fixed-point ``CV_16SC2``
        (H, W, 2) int16 and (H, W) uint16); ``raw_image_size``: ``image_size``.
    """
    st = OpenCVStorage(path, "OpenCV calibration")
    size = check_image_size("image_size", image_size)
    p1, p2 = st.matrix("P1", (3, 4)), st.matrix("P2", (3, 4))
    k1 = st.matrix(st.first("K1", "M1", "cameraMatrix1") or "K1", (3, 3))
    k2 = st.matrix(st.first("K2", "M2", "cameraMatrix2") or "K2", (3, 3))
    d1 = st.vector(st.first("D1", "distCoeffs1") or "D1")
    d2 = st.vector(st.first("D2", "distCoeffs2") or "D2")
    r1, r2 = st.matrix("R1", (3, 3)), st.matrix("R2", (3, 3))
    try:
        map_l = cv2.initUndistortRectifyMap(k1, d1, r1, p1, size, cv2.CV_16SC2)
        map_r = cv2.initUndistortRectifyMap(k2, d2, r2, p2, size, cv2.CV_16SC2)
    except cv2.error as exc:
        raise CalibrationError(f"{st.path}: cannot build rectification maps ({str(exc).strip().splitlines()[-1]})") from None
    return {"maps_left": map_l, "maps_right": map_r, "raw_image_size": size}


def _storage_text(path: PathLike, entries: list[tuple[str, Any]]) -> str:
    ext = ".xml" if str(path).lower().endswith(".xml") else ".yaml"
    fs = cv2.FileStorage(ext, cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    for key, value in entries:
        fs.write(key, value)
    return fs.releaseAndGetString()


def write_stereo(path: PathLike, *, K_left: np.ndarray, dist_left: np.ndarray, K_right: np.ndarray,  # noqa: N803
                 dist_right: np.ndarray, R: np.ndarray, T: np.ndarray, image_size: tuple[int, int],  # noqa: N803
                 rectification: dict[str, np.ndarray] | None = None) -> None:
    """Write a raw stereo calibration to OpenCV YAML/XML (XML when ``path`` ends in ``.xml``), atomically.

    Parameters
    ----------
    path : str or os.PathLike
    K_left, dist_left, K_right, dist_right, R, T, image_size
        As ``StereoRig`` holds them (pixels, metres); written as ``K1 D1 K2 D2 R T`` and
        ``image_width``/``image_height``.
    rectification : dict or None
        ``R1 R2 P1 P2 Q`` (float64 arrays) written after them for other tools; None or empty for none.
    """
    width, height = image_size
    entries: list[tuple[str, Any]] = [
        ("image_width", width), ("image_height", height),
        ("K1", K_left), ("D1", dist_left.reshape(1, -1)),
        ("K2", K_right), ("D2", dist_right.reshape(1, -1)),
        ("R", R), ("T", T.reshape(3, 1)),
    ]
    entries += list((rectification or {}).items())
    atomic_write_text(path, _storage_text(path, entries))


def write_rectified(path: PathLike, *, P_left: np.ndarray, P_right: np.ndarray, Q: np.ndarray,  # noqa: N803
                    image_size: tuple[int, int]) -> None:
    """Write a rectified geometry as ``P1``, ``P2``, ``Q`` (float64) and the image size, atomically.

    XML when ``path`` ends in ``.xml``, else YAML.
    """
    width, height = image_size
    entries = [("image_width", width), ("image_height", height), ("P1", P_left), ("P2", P_right), ("Q", Q)]
    atomic_write_text(path, _storage_text(path, entries))
