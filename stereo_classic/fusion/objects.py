"""The fusion's result: one row per detected object with its distance, 3D position and a status.

``LocalizedObjects`` is checked when built, filtered with a boolean mask (``objs[objs.ok]``) and written
as JSON rows or a short table; ``direction_phrase`` says where a point is for a person ("slightly left").
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from stereo_classic.fusion.params import METHODS, FusionInputError

__all__ = ["STATUSES", "TABLE_COLUMNS", "LocalizedObjects", "direction_phrase"]

#: The header of :meth:`LocalizedObjects.format_table`.
TABLE_COLUMNS: tuple[str, ...] = ("label", "confidence", "distance", "x (m)", "y (m)", "z (m)", "direction")

#: Every value ``LocalizedObjects.status`` can take.
#: "beyond_range" (the object is nearer than the disparity range reaches) and "pair_mismatch" (left/right swapped
#: or not a pair) are set by the frame checks of :mod:`stereo_classic.checks`.
#: "estimates_disagree": the box's consistent set and its ground contact give distances further apart than their
#: uncertainties allow (``FusionParams.ground_contact``).
STATUSES: tuple[str, ...] = ("ok", "empty_box", "too_few_depth_pixels", "out_of_range", "no_consensus",
                             "beyond_range", "pair_mismatch", "estimates_disagree")


def direction_phrase(xyz: Sequence[float] | np.ndarray) -> str:
    """Say where a point is for a person facing along +Z: "ahead", "slightly left", "right", ...

    The bearing is ``atan2(X, Z)`` (X right): below 5 degrees "ahead", below 20 degrees "slightly
    left/right", otherwise "left/right". An unknown position gives "".

    >>> direction_phrase([-0.5, 0.0, 3.0])
    'slightly left'
    """
    x, _, z = (float(c) for c in xyz)
    if not (math.isfinite(x) and math.isfinite(z)) or z <= 0:
        return ""
    angle = math.degrees(math.atan2(x, z))
    if abs(angle) < 5.0:
        return "ahead"
    side = "left" if angle < 0 else "right"
    return f"slightly {side}" if abs(angle) < 20.0 else side


def _round(value: float, digits: int) -> float | None:
    return None if not math.isfinite(value) else round(float(value), digits)


@dataclass(frozen=True, eq=False)
class LocalizedObjects:
    """Detected objects with one distance and one 3D position each (one row per detection).

    Attributes
    ----------
    labels : tuple of str, (N,)
        Class name of each object.
    class_id : (N,) int64
        Class index (-1 when the boxes came as a plain array).
    confidence : (N,) float32
        Detector score in [0, 1].
    xyxy : (N, 4) float32
        Box in left-image pixels (x0, y0, x1, y1).
    distance_m : (N,) float64
        Distance along the optical axis (Z of the consistent set's median point), metres; NaN unless status is "ok".
    xyz : (N, 3) float64
        Centroid X, Y, Z in metres in the left rectified camera frame (X right, Y down, Z forward).
    inliers : (N,) int64
        Pixels in the winning consistent set.
    valid_pixels : (N,) int64
        Pixels in the shrunk box with a known depth inside ``depth_range`` (the RANSAC input).
    inlier_ratio : (N,) float64
        ``inliers / valid_pixels`` (NaN when there were none).
    spread_m : (N,) float64
        Standard deviation of the inliers' depth, metres.
    status : tuple of str, (N,)
        One of :data:`STATUSES`.
    method : str
        "ransac" or "median".
    occluded : (N,) bool
        A nearer consistent set off the box centre (an occluder entering from the box edge, e.g. a hand in
        front of a chair) would have won; the distance is that of the set covering the object behind it
        (``FusionParams.occluder_ratio``, ``occluder_offset``). Default all False.
    nearest_m : (N,) float64
        Depth of the object's nearest surface, metres: the 10th percentile of the inliers' depth (a walking
        person or a robot reaches the near part of a car first, not its middle). NaN where there is no
        distance; default all NaN.
    distance_sigma_m : (N,) float64
        One standard uncertainty of ``distance_m``, metres (``Z**2 / (f B)`` times the disparity's: the subpixel
        precision and the spread of the set, :func:`stereo_classic.fusion.localize.disparity_sigma`). NaN where
        there is no distance; default all NaN.
    """

    labels: tuple[str, ...]
    class_id: np.ndarray
    confidence: np.ndarray
    xyxy: np.ndarray
    distance_m: np.ndarray
    xyz: np.ndarray
    inliers: np.ndarray
    valid_pixels: np.ndarray
    inlier_ratio: np.ndarray
    spread_m: np.ndarray
    status: tuple[str, ...]
    method: str = "ransac"
    occluded: np.ndarray | None = None
    nearest_m: np.ndarray | None = None
    distance_sigma_m: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.labels)
        sigma = np.full(n, np.nan) if self.distance_sigma_m is None else np.asarray(self.distance_sigma_m,
                                                                                      dtype=np.float64)
        if sigma.shape != (n,):
            raise FusionInputError(f"LocalizedObjects.distance_sigma_m must be an array of shape ({n},), got "
                                   f"{sigma.shape}")
        object.__setattr__(self, "distance_sigma_m", sigma)
        nearest = np.full(n, np.nan) if self.nearest_m is None else np.asarray(self.nearest_m, dtype=np.float64)
        if nearest.shape != (n,):
            raise FusionInputError(f"LocalizedObjects.nearest_m must be an array of shape ({n},), got {nearest.shape}")
        object.__setattr__(self, "nearest_m", nearest)
        occluded = np.zeros(n, dtype=bool) if self.occluded is None else np.asarray(self.occluded)
        if occluded.shape != (n,) or occluded.dtype != bool:
            raise FusionInputError(f"LocalizedObjects.occluded must be a bool array of shape ({n},), got "
                                   f"{occluded.dtype} {occluded.shape}")
        object.__setattr__(self, "occluded", occluded)
        shapes = {
            "class_id": (n,), "confidence": (n,), "xyxy": (n, 4), "distance_m": (n,), "xyz": (n, 3),
            "inliers": (n,), "valid_pixels": (n,), "inlier_ratio": (n,), "spread_m": (n,),
        }
        for name, shape in shapes.items():
            arr = getattr(self, name)
            if not isinstance(arr, np.ndarray) or arr.shape != shape:
                got = getattr(arr, "shape", type(arr).__name__)
                raise FusionInputError(f"LocalizedObjects.{name} must be an array of shape {shape}, got {got}")
        if len(self.status) != n:
            raise FusionInputError(f"LocalizedObjects.status must have {n} entries, got {len(self.status)}")
        bad = [s for s in self.status if s not in STATUSES]
        if bad:
            raise FusionInputError(f"LocalizedObjects.status must be one of {STATUSES}, got {bad[0]!r}")
        if self.method not in METHODS:
            raise FusionInputError(f"LocalizedObjects.method must be one of {METHODS}, got {self.method!r}")

    def __len__(self) -> int:
        return len(self.labels)

    def __getitem__(self, index: Any) -> LocalizedObjects:
        """Select rows with a boolean mask, an index array, a slice or an int; returns a new object."""
        if isinstance(index, (int, np.integer)):
            index = [int(index)]
        rows = np.arange(len(self))[index]
        return LocalizedObjects(
            labels=tuple(self.labels[i] for i in rows), class_id=self.class_id[rows],
            confidence=self.confidence[rows], xyxy=self.xyxy[rows], distance_m=self.distance_m[rows],
            xyz=self.xyz[rows], inliers=self.inliers[rows], valid_pixels=self.valid_pixels[rows],
            inlier_ratio=self.inlier_ratio[rows], spread_m=self.spread_m[rows],
            status=tuple(self.status[i] for i in rows), method=self.method, occluded=self.occluded[rows],
            nearest_m=self.nearest_m[rows], distance_sigma_m=self.distance_sigma_m[rows],
        )

    @property
    def ok(self) -> np.ndarray:
        """(N,) bool: rows whose status is "ok"."""
        return np.array([s == "ok" for s in self.status], dtype=bool)

    @property
    def directions(self) -> list[str]:
        """Human phrase per object ("ahead", "slightly left", ...), "" where unknown."""
        return [direction_phrase(p) for p in self.xyz]

    def with_status(self, rows: Any, status: str) -> LocalizedObjects:
        """A copy where ``rows`` (a boolean mask or indices) get ``status`` and, unless it is "ok", unknown
        numbers (NaN distance and position, no inliers): a measurement found to be wrong is not reported.

        >>> objs = LocalizedObjects.empty()
        >>> len(objs.with_status(np.zeros(0, bool), "beyond_range"))
        0
        """
        if status not in STATUSES:
            raise FusionInputError(f"`status` must be one of {STATUSES}, got {status!r}")
        picked = np.zeros(len(self), dtype=bool)
        picked[np.arange(len(self))[rows]] = True
        status_ = tuple(status if p else s for p, s in zip(picked, self.status))
        if status == "ok":
            return dataclasses.replace(self, status=status_)
        nan = np.where(picked, np.nan, 1.0)
        return dataclasses.replace(
            self, status=status_, distance_m=self.distance_m * nan, xyz=self.xyz * nan[:, None],
            inliers=np.where(picked, 0, self.inliers), inlier_ratio=self.inlier_ratio * nan,
            spread_m=self.spread_m * nan, occluded=self.occluded & ~picked, nearest_m=self.nearest_m * nan,
            distance_sigma_m=self.distance_sigma_m * nan)

    @classmethod
    def empty(cls, method: str = "ransac") -> LocalizedObjects:
        """No objects (every array of length 0), e.g. for a frame without detections.

        >>> len(LocalizedObjects.empty()), LocalizedObjects.empty().xyz.shape
        (0, (0, 3))
        """
        z = np.zeros(0)
        return cls(labels=(), class_id=np.zeros(0, np.int64), confidence=np.zeros(0, np.float32),
                   xyxy=np.zeros((0, 4), np.float32), distance_m=z, xyz=np.zeros((0, 3)),
                   inliers=np.zeros(0, np.int64), valid_pixels=np.zeros(0, np.int64), inlier_ratio=z,
                   spread_m=z, status=(), method=method)

    def to_json(self) -> list[dict[str, Any]]:
        """One dict per object with plain Python numbers, ``None`` where unknown.

        Numbers are rounded (metres to 1 mm, pixels to 0.01, scores to 1e-4) so that the JSON is stable
        across runs and thread counts.
        """
        out = []
        for i in range(len(self)):
            out.append({
                "label": self.labels[i],
                "class_id": int(self.class_id[i]),
                "confidence": _round(float(self.confidence[i]), 4),
                "box_xyxy": [_round(float(c), 2) for c in self.xyxy[i]],
                "status": self.status[i],
                "distance_m": _round(float(self.distance_m[i]), 3),
                "distance_sigma_m": _round(float(self.distance_sigma_m[i]), 3),
                "xyz_m": None if not np.all(np.isfinite(self.xyz[i])) else [_round(float(c), 3) for c in self.xyz[i]],
                "direction": direction_phrase(self.xyz[i]) or None,
                "inliers": int(self.inliers[i]),
                "valid_pixels": int(self.valid_pixels[i]),
                "inlier_ratio": _round(float(self.inlier_ratio[i]), 4),
                "spread_m": _round(float(self.spread_m[i]), 3),
                "nearest_m": _round(float(self.nearest_m[i]), 3),
                "occluded": bool(self.occluded[i]),
                "method": self.method,
            })
        return out

    def format_table(self, *, header: bool = True) -> str:
        """A table for people: a header line, then one aligned row per object ("" when there are none).

        Columns: ``label``, ``confidence`` (detector score), ``distance`` (metres along the optical axis),
        ``x (m)``, ``y (m)``, ``z (m)`` (median point in the left rectified camera frame: x right, y down, z
        forward) and ``direction`` ("ahead", "slightly left", ...). An object without a distance shows ``?``
        and its status in the direction column. ``header=False`` leaves the header line out.

        >>> objs = LocalizedObjects.empty()
        >>> objs.format_table()
        ''
        """
        if len(self) == 0:
            return ""
        rows = []
        for i in range(len(self)):
            conf = f"{float(self.confidence[i]):.2f}"
            if self.status[i] == "ok":
                x, y, z = self.xyz[i]
                direction = direction_phrase(self.xyz[i]) + (" (behind an occluder)" if self.occluded[i] else "")
                rows.append((self.labels[i], conf, f"{self.distance_m[i]:.2f} m", f"{x:+.2f}", f"{y:+.2f}",
                             f"{z:.2f}", direction))
            else:
                rows.append((self.labels[i], conf, "?", "", "", "",
                             f"distance unknown ({self.status[i].replace('_', ' ')})"))
        table = ([TABLE_COLUMNS] if header else []) + rows
        widths = [max(len(r[c]) for r in table) for c in range(len(TABLE_COLUMNS) - 1)]
        lines = []
        for r in table:
            cells = [r[0].ljust(widths[0])] + [r[c].rjust(widths[c]) for c in range(1, len(widths))] + [r[-1]]
            lines.append("  ".join(cells).rstrip())
        return "\n".join(lines)
