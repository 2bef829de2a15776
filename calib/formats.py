"""Readers and writers of calibration files: OpenCV FileStorage (YAML/XML), KITTI, Middlebury, ROS, OAK-D JSON.

Every reader raises ``FileNotFoundError`` for a missing file and :class:`CalibrationError` (a ``ValueError``)
naming the file and the key for anything else: empty file, missing key, non-numeric value, wrong shape.
Unit conversions (Middlebury's millimetres) happen here and nowhere else.

ROS ``camera_info`` YAML is read with ``cv2.FileStorage`` too (it copes with that simple format, with or
without a ``%YAML`` header), so PyYAML is not needed.
"""

from __future__ import annotations

import json
import logging
import math
import os
import re
import secrets
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from calib.errors import CalibrationError
from calib.rectified import RectifiedRig, check_image_size
from calib.rig import StereoRig

__all__ = [
    "load_rig",
    "read_opencv_stereo",
    "read_opencv_rectified",
    "write_stereo_opencv",
    "write_rectified_opencv",
    "read_kitti_rectified",
    "read_kitti_raw_stereo",
    "read_kitti_calib",
    "read_middlebury",
    "read_middlebury_calib",
    "read_oakd_json",
    "read_oakd_calib",
    "read_ros_camera_info",
    "read_ros_pair",
    "KITTI_OBJECT_IMAGE_SIZE",
]

log = logging.getLogger(__name__)

#: Size of most KITTI object/tracking images; ``from_kitti`` uses it when neither the file nor the caller says.
KITTI_OBJECT_IMAGE_SIZE = (1242, 375)

_PathLike = str | os.PathLike[str]


# --------------------------------------------------------------------------------------------- common helpers
def _read_text(path: _PathLike, what: str) -> tuple[Path, str]:
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


def _atomic_write_text(path: _PathLike, text: str) -> None:
    """Write ``text`` (UTF-8, ``\\n``) so that ``path`` appears complete or not at all.

    Same behaviour as ``stereo_classic.io.atomic_write`` (calib is a leaf package and must not import
    stereo_classic): a temporary file in the same folder created with mode 0o666 so that the umask decides
    the permissions, flushed and fsynced, renamed over ``path``, removed if anything fails.
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


def _finite(path: Path, key: str, value: np.ndarray) -> np.ndarray:
    if not np.all(np.isfinite(value)):
        raise CalibrationError(f"{path}: key `{key}` must be finite, got {np.asarray(value).tolist()}")
    return value


# --------------------------------------------------------------------------------------------- OpenCV FileStorage
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


class _Storage:
    """A ``cv2.FileStorage`` opened from a file (YAML, either header, or XML) with checked accessors."""

    def __init__(self, path: _PathLike, what: str = "calibration") -> None:
        self.path, text = _read_text(path, what)
        errors = []
        self.fs = None
        for variant in _storage_variants(text):
            try:
                fs = cv2.FileStorage(variant, cv2.FILE_STORAGE_READ | cv2.FILE_STORAGE_MEMORY)
            except (cv2.error, SystemError) as exc:  # cv2 raises SystemError on some parse errors
                errors.append(str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__)
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
        return key in self.keys

    def first(self, *keys: str) -> str | None:
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
        """The matrix under ``key`` (``!!opencv-matrix``, a ROS-style {rows, cols, data} map, or a flat list)."""
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
        arr = _finite(self.path, key, np.asarray(arr, dtype=np.float64))
        if shape is not None:
            ok = arr.size == int(np.prod(shape))
            if ok and arr.ndim == 2:
                ok = arr.shape == shape if len(shape) == 2 else 1 in arr.shape
            if not ok:
                raise CalibrationError(f"{self.path}: key `{key}` must have shape {shape}, got {arr.shape}")
            arr = arr.reshape(shape)
        return arr

    def vector(self, key: str) -> np.ndarray:
        arr = self.matrix(key)
        if arr.ndim == 2 and 1 not in arr.shape:
            raise CalibrationError(f"{self.path}: key `{key}` must be a vector, got shape {arr.shape}")
        return arr.reshape(-1)

    def number(self, key: str) -> float:
        node = self._node(key)
        if not (node.isReal() or node.isInt()):
            raise CalibrationError(f"{self.path}: key `{key}` must be a number")
        value = float(node.real())
        if not math.isfinite(value):
            raise CalibrationError(f"{self.path}: key `{key}` must be finite, got {value}")
        return value

    def string(self, key: str) -> str:
        node = self._node(key)
        if not node.isString():
            raise CalibrationError(f"{self.path}: key `{key}` must be a string")
        return node.string()

    def image_size(self, override: tuple[int, int] | None) -> tuple[int, int]:
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


def _rig_error(path: Path, exc: CalibrationError) -> CalibrationError:
    return CalibrationError(f"{path}: {exc}")


def read_opencv_stereo(path: _PathLike, *, image_size: tuple[int, int] | None = None) -> StereoRig:
    """A :class:`StereoRig` from an OpenCV YAML/XML with ``K1 D1 K2 D2 R T`` (``M1``/``M2`` also accepted)."""
    st = _Storage(path, "OpenCV calibration")
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
    size = st.image_size(image_size)
    try:
        return StereoRig(image_size=size, **values)
    except CalibrationError as exc:
        raise _rig_error(st.path, exc) from None


def _rectified_from_projections(path: Path, p1: np.ndarray, p2: np.ndarray, size: tuple[int, int],
                                names: tuple[str, str]) -> RectifiedRig:
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
    try:
        return RectifiedRig(focal_px=float(f), cx_left=float(p1[0, 2]), cx_right=float(p2[0, 2]), cy=float(p1[1, 2]),
                            baseline_m=float(baseline), image_size=size)
    except CalibrationError as exc:
        raise _rig_error(path, exc) from None


def read_opencv_rectified(path: _PathLike, *, image_size: tuple[int, int] | None = None, maps: bool = False) -> RectifiedRig:
    """A :class:`RectifiedRig` from an OpenCV YAML/XML with ``P1`` and ``P2`` (3x4), or else ``Q`` (4x4).

    With ``maps=True`` the file must also hold ``K1 D1 K2 D2 R1 R2``: the rig then gets the undistort/rectify
    maps of exactly that rectification, so that :meth:`RectifiedRig.rectify_pair` takes raw images.
    """
    st = _Storage(path, "OpenCV calibration")
    size = st.image_size(image_size)
    if maps:
        p1, p2 = st.matrix("P1", (3, 4)), st.matrix("P2", (3, 4))
        rig = _rectified_from_projections(st.path, p1, p2, size, ("P1", "P2"))
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
        return RectifiedRig(focal_px=rig.focal_px, cx_left=rig.cx_left, cx_right=rig.cx_right, cy=rig.cy,
                            baseline_m=rig.baseline_m, image_size=size, maps_left=map_l, maps_right=map_r, raw_image_size=size)
    if st.has("P1") and st.has("P2"):
        return _rectified_from_projections(st.path, st.matrix("P1", (3, 4)), st.matrix("P2", (3, 4)), size, ("P1", "P2"))
    if st.has("Q"):
        q = st.matrix("Q", (4, 4))
        if not (q[3, 2] > 0 and q[2, 3] > 0):
            raise CalibrationError(f"{st.path}: key `Q` must have Q[2,3] = f > 0 and Q[3,2] = 1/baseline > 0, got {q.tolist()}")
        baseline = 1.0 / q[3, 2]
        try:
            return RectifiedRig(focal_px=float(q[2, 3]), cx_left=float(-q[0, 3]), cx_right=float(-q[0, 3] + q[3, 3] * baseline),
                                cy=float(-q[1, 3]), baseline_m=float(baseline), image_size=size)
        except CalibrationError as exc:
            raise _rig_error(st.path, exc) from None
    raise CalibrationError(f"{st.path}: missing key `P1`/`P2` (or `Q`): needed for a rectified rig")


def _storage_text(path: _PathLike, entries: list[tuple[str, Any]]) -> str:
    ext = ".xml" if str(path).lower().endswith(".xml") else ".yaml"
    fs = cv2.FileStorage(ext, cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
    for key, value in entries:
        fs.write(key, value)
    return fs.releaseAndGetString()


def write_stereo_opencv(rig: StereoRig, path: _PathLike) -> None:
    """Write a :class:`StereoRig` to OpenCV YAML/XML (by extension), atomically (temp file + ``os.replace``)."""
    if not isinstance(rig, StereoRig):
        raise TypeError(f"`rig` must be a StereoRig, got {type(rig).__name__}")
    width, height = rig.image_size
    entries: list[tuple[str, Any]] = [
        ("image_width", width), ("image_height", height),
        ("K1", rig.K_left), ("D1", rig.dist_left.reshape(1, -1)),
        ("K2", rig.K_right), ("D2", rig.dist_right.reshape(1, -1)),
        ("R", rig.R), ("T", rig.T.reshape(3, 1)),
    ]
    try:
        entries += list(rig.rectification(alpha=0.0).items())
    except cv2.error as exc:  # a rig OpenCV cannot rectify still gets written
        log.warning("could not compute R1 R2 P1 P2 Q for %s: %s", path, exc)
    _atomic_write_text(path, _storage_text(path, entries))


def write_rectified_opencv(rig: RectifiedRig, path: _PathLike) -> None:
    """Write a :class:`RectifiedRig` as ``P1``, ``P2``, ``Q`` and image size, atomically."""
    if not isinstance(rig, RectifiedRig):
        raise TypeError(f"`rig` must be a RectifiedRig, got {type(rig).__name__}")
    width, height = rig.image_size
    entries = [("image_width", width), ("image_height", height), ("P1", rig.P_left), ("P2", rig.P_right), ("Q", rig.Q)]
    _atomic_write_text(path, _storage_text(path, entries))


# --------------------------------------------------------------------------------------------- ROS camera_info
def read_ros_camera_info(path: _PathLike) -> dict[str, Any]:
    """One ROS ``camera_info`` YAML: ``{"K", "D", "R", "P", "image_size", "distortion_model", "camera_name"}``."""
    st = _Storage(path, "ROS camera_info")
    model = st.string("distortion_model") if st.has("distortion_model") else "plumb_bob"
    if model not in ("plumb_bob", "rational_polynomial"):
        raise CalibrationError(f"{st.path}: key `distortion_model` is {model!r}; only plumb_bob and rational_polynomial are supported")
    out: dict[str, Any] = {
        "K": st.matrix("camera_matrix", (3, 3)),
        "D": st.vector("distortion_coefficients"),
        "R": st.matrix("rectification_matrix", (3, 3)) if st.has("rectification_matrix") else np.eye(3),
        "P": st.matrix("projection_matrix", (3, 4)),
        "image_size": st.image_size(None),
        "distortion_model": model,
        "camera_name": st.string("camera_name") if st.has("camera_name") else "",
        "path": st.path,
    }
    return out


def read_ros_pair(left_yaml: _PathLike, right_yaml: _PathLike) -> StereoRig:
    """A :class:`StereoRig` from the left and right ROS ``camera_info`` files of a stereo camera.

    ROS stores the stereo extrinsics as rectification rotations ``R`` and the right projection
    ``P[0, 3] = -fx' * baseline``; the relative pose is ``R = R_right^T R_left``, ``T = R_right^T t``.
    """
    left, right = read_ros_camera_info(left_yaml), read_ros_camera_info(right_yaml)
    if left["image_size"] != right["image_size"]:
        raise CalibrationError(f"{left['path']} and {right['path']} have different image sizes {left['image_size']} and {right['image_size']}")
    t_rect = np.linalg.solve(right["P"][:, :3], right["P"][:, 3]) - np.linalg.solve(left["P"][:, :3], left["P"][:, 3])
    if not np.linalg.norm(t_rect) > 0:
        raise CalibrationError(
            f"{right['path']}: key `projection_matrix` has no baseline (P[0,3] = 0): give the right camera's camera_info"
        )
    r_rel = right["R"].T @ left["R"]
    t_rel = right["R"].T @ t_rect
    try:
        return StereoRig(K_left=left["K"], dist_left=left["D"], K_right=right["K"], dist_right=right["D"], R=r_rel, T=t_rel,
                         image_size=left["image_size"])
    except CalibrationError as exc:
        raise CalibrationError(f"{left['path']} + {right['path']}: {exc}") from None


# --------------------------------------------------------------------------------------------- KITTI
def read_kitti_calib(path: _PathLike) -> dict[str, np.ndarray | None]:
    """All ``key: numbers`` lines of a KITTI calibration text file (values None where not numeric)."""
    path, text = _read_text(path, "KITTI calibration")
    out: dict[str, np.ndarray | None] = {}
    for line_no, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        key, sep, rest = line.partition(":")
        if not sep or not key.strip() or " " in key.strip():
            raise CalibrationError(f"{path}: line {line_no} is not `key: values`: {line[:60]!r}")
        try:
            out[key.strip()] = np.array([float(v) for v in rest.split()], dtype=np.float64)
        except ValueError:
            out[key.strip()] = None  # e.g. calib_time: 09-Jan-2012 13:57:47
    if not out:
        raise CalibrationError(f"{path}: no `key: values` lines")
    return out


def _kitti_value(path: Path, values: dict[str, np.ndarray | None], key: str, shape: tuple[int, ...]) -> np.ndarray:
    if key not in values:
        raise CalibrationError(f"{path}: missing key `{key}`")
    arr = values[key]
    if arr is None:
        raise CalibrationError(f"{path}: key `{key}` must hold numbers")
    if arr.size != int(np.prod(shape)):
        raise CalibrationError(f"{path}: key `{key}` must hold {int(np.prod(shape))} numbers ({shape}), got {arr.size}")
    return _finite(path, key, arr.reshape(shape))


def _kitti_indices(left: Any, right: Any) -> tuple[int, int]:
    for name, value in (("left", left), ("right", right)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value <= 3:
            raise CalibrationError(f"`{name}` must be a KITTI camera index 0..3, got {value!r}")
    if left == right:
        raise CalibrationError(f"`left` and `right` must be different cameras, got {left} and {right}")
    return int(left), int(right)


def read_kitti_rectified(path: _PathLike, *, left: int = 2, right: int = 3,
                         image_size: tuple[int, int] | None = None) -> RectifiedRig:
    """A :class:`RectifiedRig` from KITTI ``calib.txt`` (``P0:``..``P3:``) or raw ``calib_cam_to_cam.txt``.

    ``baseline = (P_left[0,3] - P_right[0,3]) / P_left[0,0]``. The image size comes from ``S_rect_0N`` (raw
    files), ``image_size=``, or else :data:`KITTI_OBJECT_IMAGE_SIZE` (1242x375, logged: object frames vary
    slightly in size, pass the real one when you know it).
    """
    left, right = _kitti_indices(left, right)
    values = read_kitti_calib(path)
    path = Path(path)
    if f"P_rect_0{left}" in values or "P_rect_00" in values:
        kl, kr, ks = f"P_rect_0{left}", f"P_rect_0{right}", f"S_rect_0{left}"
    else:
        kl, kr, ks = f"P{left}", f"P{right}", None
    p_left = _kitti_value(path, values, kl, (3, 4))
    p_right = _kitti_value(path, values, kr, (3, 4))
    if image_size is not None:
        size = check_image_size("image_size", image_size)
    elif ks is not None and ks in values:
        s = _kitti_value(path, values, ks, (2,))
        if not all(float(v).is_integer() and v > 0 for v in s):
            raise CalibrationError(f"{path}: key `{ks}` must be two positive integers, got {s.tolist()}")
        size = (int(s[0]), int(s[1]))
    else:
        size = KITTI_OBJECT_IMAGE_SIZE
        log.info("%s: no image size in the file, assuming KITTI's %dx%d", path, *size)
    return _rectified_from_projections(path, p_left, p_right, size, (kl, kr))


def read_kitti_raw_stereo(path: _PathLike, *, left: int = 2, right: int = 3) -> StereoRig:
    """A :class:`StereoRig` (unrectified cameras) from KITTI raw ``calib_cam_to_cam.txt``.

    Each camera ``i`` has ``X_i = R_0i X_0 + T_0i``; the pose of ``right`` relative to ``left`` follows.
    """
    left, right = _kitti_indices(left, right)
    values = read_kitti_calib(path)
    path = Path(path)
    if f"K_0{left}" not in values and f"P{left}" in values:
        raise CalibrationError(
            f"{path}: a KITTI object calib.txt holds only rectified projections (no `K_0{left}`): use RectifiedRig.from_kitti"
        )

    def cam(i: int) -> tuple[np.ndarray, ...]:
        return (_kitti_value(path, values, f"K_0{i}", (3, 3)), _kitti_value(path, values, f"D_0{i}", (5,)),
                _kitti_value(path, values, f"R_0{i}", (3, 3)), _kitti_value(path, values, f"T_0{i}", (3,)),
                _kitti_value(path, values, f"S_0{i}", (2,)))

    kl, dl, rl, tl, sl = cam(left)
    kr, dr, rr, tr, sr = cam(right)
    if not np.array_equal(sl, sr) or not all(float(v).is_integer() and v > 0 for v in sl):
        raise CalibrationError(f"{path}: keys `S_0{left}`/`S_0{right}` must be the same two positive integers, got {sl.tolist()} and {sr.tolist()}")
    r_rel = rr @ rl.T
    t_rel = tr - r_rel @ tl
    try:
        return StereoRig(K_left=kl, dist_left=dl, K_right=kr, dist_right=dr, R=r_rel, T=t_rel, image_size=(int(sl[0]), int(sl[1])))
    except CalibrationError as exc:
        raise _rig_error(path, exc) from None


# --------------------------------------------------------------------------------------------- Middlebury
_MATRIX_RE = re.compile(r"^\[(.*)\]$")


def read_middlebury_calib(path: _PathLike) -> dict[str, Any]:
    """All ``key=value`` entries of a Middlebury 2014 ``calib.txt``, as stored (``cam0``/``cam1`` as 3x3 arrays,
    ``baseline`` still in millimetres, ``ndisp``/``width``/``height``/``vmin``/``vmax`` as numbers)."""
    path, text = _read_text(path, "Middlebury calib.txt")
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


def read_middlebury(calib_txt: _PathLike, *, image_size: tuple[int, int] | None = None) -> RectifiedRig:
    """A :class:`RectifiedRig` from Middlebury ``calib.txt``; ``baseline`` is converted from mm to metres."""
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
        _finite(path, key, cam)
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

    try:
        return RectifiedRig(focal_px=float(cam0[0, 0]) * factor, cx_left=float(px(cam0[0, 2])),
                            cx_right=float(px(cam0[0, 2] + doffs)), cy=float(px(cam0[1, 2])),
                            baseline_m=float(baseline_mm) / 1000.0, image_size=size)
    except CalibrationError as exc:
        raise _rig_error(path, exc) from None


# --------------------------------------------------------------------------------------------- OAK-D JSON
def read_oakd_calib(path: _PathLike) -> dict[str, Any]:
    """The stereodemo/OAK-D JSON object as stored, with ``depth_range`` (when present) checked and returned
    as a ``(near, far)`` tuple of metres (finite, 0 < near < far)."""
    path, text = _read_text(path, "OAK-D calibration JSON")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise CalibrationError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise CalibrationError(f"{path}: expected a JSON object at the top level, got {type(data).__name__}")
    if "depth_range" in data:
        dr = data["depth_range"]
        if not (isinstance(dr, list) and len(dr) == 2 and all(
            not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v) for v in dr
        ) and 0 < dr[0] < dr[1]):
            raise CalibrationError(f"{path}: key `depth_range` must be [near, far] in metres with 0 < near < far, got {dr!r}")
        data["depth_range"] = (float(dr[0]), float(dr[1]))
    return data


def read_oakd_json(path: _PathLike) -> RectifiedRig:
    """A :class:`RectifiedRig` from the stereodemo/OAK-D JSON: ``width``, ``height``, ``fx``, ``cx0``, ``cx1``,
    ``cy``, ``baseline_meters`` (``fy`` optional; fx is used)."""
    data = read_oakd_calib(path)
    path = Path(path)

    def num(key: str) -> float:
        if key not in data:
            raise CalibrationError(f"{path}: missing key `{key}`")
        value = data[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise CalibrationError(f"{path}: key `{key}` must be a finite number, got {value!r}")
        return float(value)

    width, height = num("width"), num("height")
    if not (width.is_integer() and height.is_integer() and width > 0 and height > 0):
        raise CalibrationError(f"{path}: keys `width`/`height` must be positive integers, got {data['width']!r}/{data['height']!r}")
    try:
        return RectifiedRig(focal_px=num("fx"), cx_left=num("cx0"), cx_right=num("cx1"), cy=num("cy"),
                            baseline_m=num("baseline_meters"), image_size=(int(width), int(height)))
    except CalibrationError as exc:
        raise _rig_error(path, exc) from None


# --------------------------------------------------------------------------------------------- sniffing
def load_rig(path: _PathLike, *, image_size: tuple[int, int] | None = None) -> StereoRig | RectifiedRig:
    """Read any supported calibration file, recognised by its content.

    - ``.json`` with ``fx``/``cx0``/``cx1``: OAK-D / stereodemo -> :class:`RectifiedRig`
    - text with ``cam0=``: Middlebury ``calib.txt`` -> :class:`RectifiedRig`
    - text with ``P2:`` or ``P_rect_02:``: KITTI -> :class:`RectifiedRig` (left P2, right P3)
    - OpenCV YAML/XML with ``K1``/``M1``: -> :class:`StereoRig`; with only ``P1``/``P2`` or ``Q``: -> :class:`RectifiedRig`

    A single ROS ``camera_info`` file is refused (it describes one camera): use ``StereoRig.from_ros(left, right)``.
    """
    p, text = _read_text(path, "calibration")
    head = text.lstrip()
    if head.startswith("{"):
        return read_oakd_json(p)
    if re.search(r"^\s*cam0\s*=", text, re.MULTILINE):
        return read_middlebury(p, image_size=image_size)
    if not head.startswith(("%YAML", "<")) and re.search(r"^(P_rect_0\d|P\d):[ \t]*[-+.\d]", text, re.MULTILINE):
        return read_kitti_rectified(p, image_size=image_size)
    st = _Storage(p)
    if st.first("K1", "M1", "cameraMatrix1", "camera_matrix_left"):
        return read_opencv_stereo(p, image_size=image_size)
    if st.has("P1") and st.has("P2") or st.has("Q"):
        return read_opencv_rectified(p, image_size=image_size)
    if st.has("camera_matrix"):
        raise CalibrationError(f"{p}: a ROS camera_info file describes one camera: use StereoRig.from_ros(left_yaml, right_yaml)")
    raise CalibrationError(
        f"{p}: unrecognised calibration file (expected OpenCV K1/D1/K2/D2/R/T or P1/P2/Q, KITTI, Middlebury or OAK-D JSON); "
        f"keys found: {', '.join(st.keys[:10])}"
    )
