"""Disparity error metrics against ground truth, in three views and per region.

Conventions (the project's): disparity is float32 pixels, ``d = x_left - x_right``; NaN (or any
non-finite value) means unknown. Pixels without ground truth never count, in any view.

Three views, always reported together, because methods of different density cannot be ranked by one:

- ``"dense"``: the method's unknown pixels are first filled the way the KITTI stereo devkit does
  (:func:`kitti_interpolate`, the devkit's ``interpolateBackground``), identically for every method,
  then every pixel with ground truth counts. A method is neither rewarded nor punished for leaving
  pixels unknown: a hole costs what the background fill next to it is worth. This is the fair view.
- ``"all"`` (unknown-is-bad, "ukb"): every pixel with ground truth counts; a pixel the method left
  unknown counts as bad (for bad-t and D1). EPE and RMS are not defined for a pixel without an estimate,
  so in this view they are ``None``; the density says how many pixels have one. This rewards density.
- ``"valid"``: only pixels with ground truth *and* an estimate count. This rewards leaving hard pixels
  out; read it with the density.

Regions: ``"full"`` (every pixel with ground truth), ``"nonocc"`` (non-occluded pixels, where a mask
exists) and ``"border"`` (the left band ``x < max_disparity``, where a left-view matcher cannot see
the whole disparity range; OpenCV leaves it unknown).

Example
-------
>>> import numpy as np
>>> gt = np.array([[1.0, 2.0, np.nan, 4.0]], np.float32)
>>> pred = np.array([[1.0, 5.0, 3.0, np.nan]], np.float32)
>>> m = error_metrics(pred, gt)
>>> m["all"]["bad2"], m["valid"]["bad2"], m["all"]["density"]
(66.66666666666667, 50.0, 66.66666666666667)
>>> kitti_interpolate(pred).tolist()  # the unknown right border takes its left neighbour
[[1.0, 5.0, 3.0, 3.0]]
>>> m["dense"]["bad2"]
33.333333333333336
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

__all__ = [
    "BAD_THRESHOLDS",
    "METRIC_NAMES",
    "VIEWS",
    "REGIONS",
    "error_metrics",
    "kitti_interpolate",
    "scene_metrics",
    "mean_metrics",
    "visible_in_both",
]

#: Thresholds (pixels) of the bad-t percentages.
BAD_THRESHOLDS: tuple[float, ...] = (0.5, 1.0, 2.0, 4.0)
#: Metric keys of one view, in display order.
METRIC_NAMES: tuple[str, ...] = ("bad0.5", "bad1", "bad2", "bad4", "epe", "rms", "d1", "density", "n")
VIEWS: tuple[str, ...] = ("dense", "all", "valid")
REGIONS: tuple[str, ...] = ("full", "nonocc", "border")


def _bad_key(threshold: float) -> str:
    return f"bad{threshold:g}"


def _as_disparity(name: str, value: object) -> np.ndarray:
    array = np.asarray(value)
    if array.ndim != 2:
        raise ValueError(f"`{name}` must be a 2-D (H, W) disparity array, got shape {array.shape}")
    if not (np.issubdtype(array.dtype, np.floating) or np.issubdtype(array.dtype, np.integer)):
        raise ValueError(f"`{name}` must hold real numbers (float disparity, NaN unknown), got dtype {array.dtype}")
    return array.astype(np.float64, copy=False)


def kitti_interpolate(disparity: np.ndarray) -> np.ndarray:
    """Fill unknown pixels as the KITTI stereo devkit does before scoring (``interpolateBackground``).

    Row by row, each run of unknown pixels between two known ones takes the smaller (background) of
    its two neighbours; unknown runs at the row's ends take the nearest known value. Then column by
    column, rows that are still unknown above the first or below the last known row take the nearest
    known value. Rows without any known pixel between known rows stay unknown, as in the devkit (they
    then count as bad). The same fill for every method: this is what makes the dense view fair.

    Parameters
    ----------
    disparity : (H, W) float array, NaN (or any non-finite value) unknown

    Returns
    -------
    (H, W) float64 array
    """
    disp = _as_disparity("disparity", disparity).copy()
    h, w = disp.shape
    valid = np.isfinite(disp)
    if w == 0 or h == 0:
        return disp
    cols = np.arange(w)
    # index of the last known pixel at or left of x (-1: none) and the first at or right of x (w: none)
    left_idx = np.maximum.accumulate(np.where(valid, cols, -1), axis=1)
    right_idx = np.minimum.accumulate(np.where(valid, cols, w)[:, ::-1], axis=1)[:, ::-1]
    rows = np.arange(h)[:, None]
    left_val = np.where(left_idx >= 0, disp[rows, np.clip(left_idx, 0, w - 1)], np.nan)
    right_val = np.where(right_idx < w, disp[rows, np.clip(right_idx, 0, w - 1)], np.nan)
    inner = ~valid & (left_idx >= 0) & (right_idx < w)
    disp[inner] = np.minimum(left_val[inner], right_val[inner])
    only_right = ~valid & (left_idx < 0) & (right_idx < w)
    disp[only_right] = right_val[only_right]
    only_left = ~valid & (left_idx >= 0) & (right_idx >= w)
    disp[only_left] = left_val[only_left]
    known_rows = np.flatnonzero(np.isfinite(disp).all(axis=1))
    if known_rows.size:
        disp[: known_rows[0]] = disp[known_rows[0]]
        disp[known_rows[-1] + 1:] = disp[known_rows[-1]]
    return disp


def visible_in_both(gt_disparity: np.ndarray, tolerance: float = 1.0) -> np.ndarray:
    """(H, W) bool: the ground-truth pixels whose scene point the right image also sees, from the ground truth alone.

    A left pixel ``x`` with true disparity ``d`` shows in the right image at ``x - d``. It is not seen there when
    ``x - d`` lies outside the right image, or when a nearer surface lands on the same right pixel: a right-view
    z-buffer of the ground truth (per right column the largest disparity that lands on it, at the nearest column)
    holds, at ``x - d`` (either column around it when it falls between two), a disparity more than ``tolerance``
    px larger than ``d``. Those pixels have no correspondence: a two-view matcher cannot measure them, only guess
    them, so the share of the ground truth that is visible in both views bounds the density of correct
    measurements any matcher reaches. On Adirondack and Motorcycle it marks 7.7 and 11.3 % of the ground truth occluded, against their
    datasets' occlusion masks' 8.2 and 11.5 % (the two agree on 99.3 and 98.3 % of the pixels);
    ``benchmarks.density`` prints the share per family.

    It needs dense ground truth. With LiDAR the z-buffer misses the surfaces without ground truth (too few pixels
    found hidden), and LiDAR points that leak through a foreground edge (the scanner sees past it where the
    camera does not) hide background pixels the camera sees: on the DrivingStereo frames 85 % of the pixels it
    calls hidden and the matcher measures are within 2 px. Read it there as a rough share, not a bound.

    >>> gt = np.array([[1, 1, 1, 1, 3, 3, 1, 1]], np.float32)  # a nearer block (3 px) on a 1 px background
    >>> visible_in_both(gt).astype(int).tolist()  # x=0: outside the right image; x=2, 3: behind the block
    [[0, 1, 0, 0, 1, 1, 1, 1]]
    """
    gt = _as_disparity("gt_disparity", gt_disparity)
    if not (math.isfinite(tolerance) and tolerance >= 0):
        raise ValueError(f"`tolerance` must be a finite number of pixels >= 0, got {tolerance!r}")
    h, w = gt.shape
    known = np.isfinite(gt)
    with np.errstate(invalid="ignore"):
        xr = np.arange(w, dtype=np.float64)[None, :] - gt  # NaN where unknown
        inside = known & (xr >= -0.5) & (xr < w - 0.5)
    rows = np.broadcast_to(np.arange(h)[:, None], gt.shape)
    zbuf = np.full(h * w, -np.inf)
    at = rows[inside] * w + np.floor(xr[inside] + 0.5).astype(np.int64)
    np.maximum.at(zbuf, at, gt[inside])
    zbuf = zbuf.reshape(h, w)
    xr_in = np.where(inside, xr, 0.0)
    lo = np.clip(np.floor(xr_in).astype(np.int64), 0, w - 1)
    hi = np.clip(np.ceil(xr_in).astype(np.int64), 0, w - 1)
    nearest = np.maximum(zbuf[rows, lo], zbuf[rows, hi])
    with np.errstate(invalid="ignore"):
        return inside & ~(nearest > gt + tolerance)


def error_metrics(
    disparity: np.ndarray,
    gt_disparity: np.ndarray,
    mask: np.ndarray | None = None,
    *,
    thresholds: Sequence[float] = BAD_THRESHOLDS,
) -> dict[str, dict[str, float | int | None]]:
    """Error of one disparity map against ground truth over one region, in both views.

    Parameters
    ----------
    disparity : (H, W) float array, pixels
        The estimate; NaN or +-inf where unknown.
    gt_disparity : (H, W) float array, pixels
        Ground truth; NaN or +-inf where there is none (those pixels never count).
    mask : (H, W) bool array, optional
        The region to evaluate (True = counted). ``None`` is the whole image.
    thresholds : sequence of float
        Error thresholds (pixels) of the bad-t percentages.

    Returns
    -------
    dict
        ``{"dense": {...}, "all": {...}, "valid": {...}}``; each view maps ``"bad0.5"``, ``"bad1"``, ``"bad2"``,
        ``"bad4"``, ``"d1"`` and ``"density"`` to percentages, ``"epe"`` and ``"rms"`` to pixels and
        ``"n"`` to the number of pixels counted. A value that is not defined (no pixel counted, or EPE
        in the "all" view) is ``None``.

    Raises
    ------
    ValueError
        Arrays that are not 2-D, differ in shape, or are not numeric; a mask that is not boolean.
    """
    pred = _as_disparity("disparity", disparity)
    gt = _as_disparity("gt_disparity", gt_disparity)
    if pred.shape != gt.shape:
        raise ValueError(f"`disparity` shape {pred.shape} must equal `gt_disparity` shape {gt.shape}")
    known = np.isfinite(gt)
    if mask is not None:
        mask_arr = np.asarray(mask)
        if mask_arr.shape != gt.shape:
            raise ValueError(f"`mask` shape {mask_arr.shape} must equal `gt_disparity` shape {gt.shape}")
        if mask_arr.dtype != np.bool_:
            raise ValueError(f"`mask` must be a boolean array, got dtype {mask_arr.dtype}")
        known &= mask_arr
    for t in thresholds:
        if not (math.isfinite(t) and t >= 0):
            raise ValueError(f"`thresholds` must be finite and >= 0, got {t!r}")

    has_estimate = np.isfinite(pred)
    n_known = int(known.sum())
    counted = known & has_estimate
    n_valid = int(counted.sum())
    n_unknown = n_known - n_valid
    err = np.abs(pred[counted] - gt[counted])
    gt_counted = np.abs(gt[counted])
    d1_bad = int(np.count_nonzero((err > 3.0) & (err > 0.05 * gt_counted)))

    def pct(count: int, total: int) -> float | None:
        return 100.0 * count / total if total else None

    views: dict[str, dict[str, float | int | None]] = {"dense": {}, "all": {}, "valid": {}}
    filled = kitti_interpolate(pred)
    dense_err = np.abs(filled[known] - gt[known])  # NaN where the fill left a pixel unknown: bad
    dense_bad = ~(dense_err <= np.inf)
    for t in thresholds:
        views["dense"][_bad_key(t)] = pct(int(np.count_nonzero(dense_bad | (dense_err > t))), n_known)
    finite_err = dense_err[~dense_bad]
    views["dense"]["epe"] = float(finite_err.mean()) if finite_err.size and not dense_bad.any() else None
    views["dense"]["rms"] = (float(np.sqrt(np.mean(finite_err * finite_err)))
                             if finite_err.size and not dense_bad.any() else None)
    d1_dense = dense_bad | ((dense_err > 3.0) & (dense_err > 0.05 * np.abs(gt[known])))
    views["dense"]["d1"] = pct(int(np.count_nonzero(d1_dense)), n_known)
    for t in thresholds:
        bad = int(np.count_nonzero(err > t))
        views["all"][_bad_key(t)] = pct(bad + n_unknown, n_known)
        views["valid"][_bad_key(t)] = pct(bad, n_valid)
    epe = float(err.mean()) if n_valid else None
    rms = float(np.sqrt(np.mean(err * err))) if n_valid else None
    views["all"]["epe"] = None
    views["all"]["rms"] = None
    views["valid"]["epe"] = epe
    views["valid"]["rms"] = rms
    views["all"]["d1"] = pct(d1_bad + n_unknown, n_known)
    views["valid"]["d1"] = pct(d1_bad, n_valid)
    density = pct(n_valid, n_known)
    views["dense"]["density"] = density
    views["dense"]["n"] = n_known
    views["all"]["density"] = density
    views["valid"]["density"] = density
    views["all"]["n"] = n_known
    views["valid"]["n"] = n_valid
    return views


def scene_metrics(
    disparity: np.ndarray,
    gt_disparity: np.ndarray,
    *,
    nonocc_mask: np.ndarray | None = None,
    max_disparity: int | None = None,
) -> dict[str, dict[str, dict[str, float | int | None]]]:
    """Metrics of one scene per region: ``{"full": ..., "nonocc": ..., "border": ...}``.

    Parameters
    ----------
    disparity, gt_disparity : (H, W) float arrays, pixels, NaN unknown
    nonocc_mask : (H, W) bool array, optional
        True where the pixel is visible in both views. Without it there is no ``"nonocc"`` region.
    max_disparity : int, optional
        Width of the left border band (``x < max_disparity``). Without it there is no ``"border"``.

    Returns
    -------
    dict
        Region name to the :func:`error_metrics` result of that region.
    """
    gt = np.asarray(gt_disparity)
    out = {"full": error_metrics(disparity, gt)}
    if nonocc_mask is not None:
        out["nonocc"] = error_metrics(disparity, gt, np.asarray(nonocc_mask, dtype=bool))
    if max_disparity is not None:
        if isinstance(max_disparity, bool) or not isinstance(max_disparity, (int, np.integer)) or max_disparity < 0:
            raise ValueError(f"`max_disparity` must be an integer >= 0, got {max_disparity!r}")
        if gt.ndim != 2:
            raise ValueError(f"`gt_disparity` must be a 2-D (H, W) disparity array, got shape {gt.shape}")
        band = np.zeros(gt.shape, dtype=bool)
        band[:, : int(max_disparity)] = True
        out["border"] = error_metrics(disparity, gt, band)
    return out


def mean_metrics(per_scene: Sequence[Mapping]) -> dict:
    """Average nested metric dicts over scenes, key by key, ignoring ``None`` (each scene weighs the same).

    ``"n"`` is summed instead of averaged. A key that is ``None`` in every scene stays ``None``.
    """
    if not per_scene:
        return {}
    first = per_scene[0]
    out: dict = {}
    keys: list = list(first.keys())
    for other in per_scene[1:]:
        keys += [k for k in other.keys() if k not in keys]
    for key in keys:
        values = [scene[key] for scene in per_scene if key in scene]
        if any(isinstance(v, Mapping) for v in values):
            out[key] = mean_metrics([v for v in values if isinstance(v, Mapping)])
            continue
        numbers = [float(v) for v in values if v is not None]
        if key == "n":
            out[key] = int(sum(numbers))
        else:
            out[key] = float(np.mean(numbers)) if numbers else None
    return out
