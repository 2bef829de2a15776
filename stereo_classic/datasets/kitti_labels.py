"""KITTI 3D object labels (``label_2/<id>.txt``) and the LiDAR points inside each labelled 3D box.

One row per object, 15 values (a 16th, ``score``, in detection result files)::

    type truncated occluded alpha x1 y1 x2 y2 h w l x y z rotation_y [score]

``box2d`` is the 2D box in left-image (camera 2) pixels; ``dimensions`` (h, w, l) metres; ``location`` (x, y, z)
metres, the bottom centre of the 3D box in the *rectified camera-0 frame* (x right, y down, z forward);
``rotation_y`` the yaw about the camera y axis in radians. The left colour camera (camera 2) sits in the same
rectified plane, offset along x (and by millimetres along z: ``P2[2, 3]``), so a depth along its optical axis is
``z + P2[2, 3]``. ``DontCare`` rows mark unlabelled regions (their 3D values are -1/-1000).

Example
-------
>>> import numpy as np
>>> label = KittiLabel("Car", 0.0, 0, 0.0, (0.0, 0.0, 10.0, 10.0), (1.5, 1.6, 4.0), (0.0, 1.5, 10.0), 0.0)
>>> points = np.array([[0.0, 1.0, 10.0], [0.0, 1.0, 13.0], [0.0, -0.5, 10.0]])  # centre, behind, above
>>> points_in_box(points, label).tolist()
[True, False, False]
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stereo_classic.io import FileFormatError

__all__ = [
    "KittiLabel",
    "KittiLabelError",
    "box_corners",
    "lidar_points_in_labels",
    "points_in_box",
    "read_kitti_labels",
    "velodyne_to_rect",
]

#: The 15 fields of a label row, in file order (``box2d``, ``dimensions``, ``location`` span 4, 3, 3 values).
FIELDS: tuple[str, ...] = ("type", "truncated", "occluded", "alpha", "x1", "y1", "x2", "y2", "h", "w", "l",
                           "x", "y", "z", "rotation_y")


class KittiLabelError(FileFormatError):
    """A KITTI label file row that cannot be read; the message names the file, the line, the field and the value."""


@dataclass(frozen=True)
class KittiLabel:
    """One object of a KITTI label file.

    Attributes
    ----------
    type : str
        "Car", "Van", "Truck", "Pedestrian", "Person_sitting", "Cyclist", "Tram", "Misc" or "DontCare".
    truncated : float
        Fraction of the object outside the image, 0..1 (-1 for DontCare).
    occluded : int
        0 fully visible, 1 partly occluded, 2 largely occluded, 3 unknown (-1 for DontCare).
    alpha : float
        Observation angle, radians.
    box2d : (x1, y1, x2, y2) float
        2D box in left-image pixels.
    dimensions : (h, w, l) float
        3D box height, width, length, metres.
    location : (x, y, z) float
        Bottom centre of the 3D box, metres, rectified camera-0 frame (x right, y down, z forward).
    rotation_y : float
        Yaw about the camera y axis, radians (0: the object's length along camera x).
    score : float or None
        Detection score (result files only).
    line : int
        Line number in the file (1-based; 0 when built by hand).
    """

    type: str
    truncated: float
    occluded: int
    alpha: float
    box2d: tuple[float, float, float, float]
    dimensions: tuple[float, float, float]
    location: tuple[float, float, float]
    rotation_y: float
    score: float | None = None
    line: int = 0

    @property
    def is_dontcare(self) -> bool:
        """True for ``DontCare`` rows (unlabelled regions, no 3D box)."""
        return self.type == "DontCare"


def _parse_float(path: Path, line_no: int, field: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise KittiLabelError(f"{path}: line {line_no}, field `{field}` must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise KittiLabelError(f"{path}: line {line_no}, field `{field}` must be finite, got {text!r}")
    return value


def _parse_row(path: Path, line_no: int, tokens: list[str]) -> KittiLabel:
    if len(tokens) not in (15, 16):
        raise KittiLabelError(f"{path}: line {line_no} must hold 15 values (16 with a score): "
                              f"{' '.join(FIELDS)} [score], got {len(tokens)}")
    kind = tokens[0]
    v = {name: _parse_float(path, line_no, name, text) for name, text in zip(FIELDS[1:], tokens[1:15])}
    score = _parse_float(path, line_no, "score", tokens[15]) if len(tokens) == 16 else None

    def bad(field: str, expected: str) -> KittiLabelError:
        return KittiLabelError(f"{path}: line {line_no}, field `{field}` must be {expected}, got {tokens[FIELDS.index(field)]!r}")

    dontcare = kind == "DontCare"
    if not dontcare:
        if not 0.0 <= v["truncated"] <= 1.0:
            raise bad("truncated", "in 0..1")
        if v["occluded"] not in (0.0, 1.0, 2.0, 3.0):
            raise bad("occluded", "0, 1, 2 or 3")
        for name in ("h", "w", "l"):
            if v[name] <= 0:
                raise bad(name, "a positive size in metres")
    elif not v["occluded"].is_integer():
        raise bad("occluded", "an integer")
    if v["x2"] < v["x1"]:
        raise bad("x2", f"at least x1 ({tokens[4]})")
    if v["y2"] < v["y1"]:
        raise bad("y2", f"at least y1 ({tokens[5]})")
    return KittiLabel(
        type=kind, truncated=v["truncated"], occluded=int(v["occluded"]), alpha=v["alpha"],
        box2d=(v["x1"], v["y1"], v["x2"], v["y2"]), dimensions=(v["h"], v["w"], v["l"]),
        location=(v["x"], v["y"], v["z"]), rotation_y=v["rotation_y"], score=score, line=line_no,
    )


def read_kitti_labels(path: str | os.PathLike, *, dontcare: bool = True) -> tuple[KittiLabel, ...]:
    """Read a KITTI object label file (``label_2/<id>.txt``): one :class:`KittiLabel` per row, in file order.

    Parameters
    ----------
    path : str or os.PathLike
    dontcare : bool, keyword-only
        Keep ``DontCare`` rows (default True: the file as stored; ``label.line`` keeps its row number either way).

    Returns
    -------
    tuple of KittiLabel
        Empty for an empty file (a frame without objects).

    Raises
    ------
    FileNotFoundError
        No such file (or a folder).
    KittiLabelError (a FileFormatError, a ValueError)
        A malformed row: the message names the line, the field and the value.
    """
    p = Path(os.fspath(path))
    if not p.exists():
        raise FileNotFoundError(f"KITTI label file not found: {p}")
    if p.is_dir():
        raise FileNotFoundError(f"KITTI label file: expected a file, got a directory: {p}")
    try:
        text = p.read_text(encoding="ascii")
    except UnicodeDecodeError:
        raise KittiLabelError(f"{p}: not a KITTI label file (not ASCII text)") from None
    labels = []
    for line_no, line in enumerate(text.splitlines(), 1):
        tokens = line.split()
        if not tokens:
            continue
        label = _parse_row(p, line_no, tokens)
        if dontcare or not label.is_dontcare:
            labels.append(label)
    return tuple(labels)


def _rotation_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def box_corners(label: KittiLabel) -> np.ndarray:
    """The 8 corners of the label's 3D box, (8, 3) float64 metres in the rectified camera-0 frame.

    Corners 0-3 are the bottom face (y = location y), 4-7 the top face, in KITTI devkit order.
    """
    if label.is_dontcare:
        raise ValueError(f"`label` (line {label.line}) is a DontCare row: it has no 3D box")
    h, w, length = label.dimensions
    x = length / 2 * np.array([1, 1, -1, -1, 1, 1, -1, -1])
    y = -h * np.array([0, 0, 0, 0, 1, 1, 1, 1])
    z = w / 2 * np.array([1, -1, -1, 1, 1, -1, -1, 1])
    return (_rotation_y(label.rotation_y) @ np.vstack([x, y, z])).T + np.asarray(label.location)


def points_in_box(points: np.ndarray, label: KittiLabel) -> np.ndarray:
    """Which points lie inside the label's 3D box (faces included).

    Parameters
    ----------
    points : (N, 3) float, metres, rectified camera-0 frame (see :func:`velodyne_to_rect`)
    label : KittiLabel (not DontCare)

    Returns
    -------
    (N,) bool
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise ValueError(f"`points` must have shape (N, 3), got {pts.shape}")
    if label.is_dontcare:
        raise ValueError(f"`label` (line {label.line}) is a DontCare row: it has no 3D box")
    h, w, length = label.dimensions
    local = (pts - np.asarray(label.location)) @ _rotation_y(label.rotation_y)  # R^T p, row-wise
    eps = 1e-9
    return ((np.abs(local[:, 0]) <= length / 2 + eps) & (np.abs(local[:, 2]) <= w / 2 + eps)
            & (local[:, 1] <= eps) & (local[:, 1] >= -h - eps))


def velodyne_to_rect(points: np.ndarray, *, R0_rect: np.ndarray, Tr_velo_to_cam: np.ndarray) -> np.ndarray:
    """Velodyne points into the rectified camera-0 frame: ``R0_rect @ (Tr_velo_to_cam @ [x y z 1])``.

    Parameters
    ----------
    points : (N, 3) or (N, 4) float, metres (a 4th column, reflectance, is ignored)
    R0_rect : (3, 3); Tr_velo_to_cam : (3, 4)

    Returns
    -------
    (N, 3) float64 metres (x right, y down, z forward); non-finite input rows stay non-finite.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] not in (3, 4):
        raise ValueError(f"`points` must have shape (N, 3) or (N, 4), got {pts.shape}")
    R0 = np.asarray(R0_rect, dtype=np.float64)
    Tr = np.asarray(Tr_velo_to_cam, dtype=np.float64)
    for name, m, shape in (("R0_rect", R0, (3, 3)), ("Tr_velo_to_cam", Tr, (3, 4))):
        if m.shape != shape or not np.isfinite(m).all():
            raise ValueError(f"`{name}` must be a finite {shape} matrix, got shape {m.shape}")
    return (R0 @ (Tr[:, :3] @ pts[:, :3].T + Tr[:, 3:4])).T


def lidar_points_in_labels(points: np.ndarray, labels: tuple[KittiLabel, ...] | list[KittiLabel], *,
                           R0_rect: np.ndarray, Tr_velo_to_cam: np.ndarray) -> list[np.ndarray | None]:
    """Per label, the LiDAR points inside its 3D box, in the rectified camera-0 frame.

    Parameters
    ----------
    points : (N, 3) or (N, 4) float, Velodyne frame (``read_velodyne``)
    labels : sequence of KittiLabel
    R0_rect, Tr_velo_to_cam : the calibration's matrices (``read_kitti_calib_file``)

    Returns
    -------
    list, one entry per label: (M, 3) float64 metres (x right, y down, z forward; M may be 0), None for DontCare.
    """
    rect = velodyne_to_rect(points, R0_rect=R0_rect, Tr_velo_to_cam=Tr_velo_to_cam)
    rect = rect[np.isfinite(rect).all(axis=1)]
    return [None if label.is_dontcare else rect[points_in_box(rect, label)] for label in labels]
