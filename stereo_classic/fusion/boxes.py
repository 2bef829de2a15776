"""Detection boxes for the fusion: the boxes and their labels from detections, and the shrunk pixel range.

Both :func:`~stereo_classic.fusion.localize` and
:func:`~stereo_classic.fusion.sparse_depth_reference` shrink a box the same way, through
:func:`shrunk_pixel_box`, so the LiDAR reference sees exactly the pixels the fusion sees.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from stereo_classic.fusion.params import FusionInputError

__all__ = ["boxes_and_meta", "shrunk_pixel_box"]


def boxes_and_meta(detections: Any) -> tuple[np.ndarray, tuple[str, ...], np.ndarray, np.ndarray]:
    """Boxes, labels, class ids and scores of ``detections``, checked.

    Parameters
    ----------
    detections : detectors.Detections or (N, 4) array_like
        Anything with ``xyxy``, ``confidence`` and ``class_id`` (and ``labels`` or ``class_names``), or plain
        boxes (x0, y0, x1, y1) in pixels, which get the label "object", class id -1 and confidence 1.

    Returns
    -------
    xyxy : (N, 4) float64, pixels
    labels : tuple of N str
    class_id : (N,) int64
    confidence : (N,) float32

    Raises
    ------
    FusionInputError (ValueError)
        Not boxes, a box coordinate that is not finite, or a box with ``x1 < x0`` or ``y1 < y0``.

    Examples
    --------
    >>> xyxy, labels, class_id, confidence = boxes_and_meta([[0, 0, 4, 2]])
    >>> xyxy.shape, labels, class_id.tolist()
    ((1, 4), ('object',), [-1])
    """
    xyxy, labels, class_id, confidence = _read_detections(detections)
    if not np.all(np.isfinite(xyxy)):
        raise FusionInputError("`detections` box coordinates must be finite")
    if np.any(xyxy[:, 2] < xyxy[:, 0]) or np.any(xyxy[:, 3] < xyxy[:, 1]):
        raise FusionInputError("`detections` boxes must be (x0, y0, x1, y1) with x1 >= x0 and y1 >= y0")
    return xyxy, labels, class_id, confidence


def _read_detections(detections: Any) -> tuple[np.ndarray, tuple[str, ...], np.ndarray, np.ndarray]:
    if isinstance(detections, np.ndarray) or isinstance(detections, (list, tuple)):
        try:
            xyxy = np.asarray(detections, dtype=np.float64)
        except (TypeError, ValueError) as exc:
            raise FusionInputError(f"`detections` as an array must be numeric (N, 4) boxes: {exc}") from None
        if xyxy.size == 0:
            xyxy = xyxy.reshape(0, 4)
        if xyxy.ndim != 2 or xyxy.shape[1] != 4:
            raise FusionInputError(f"`detections` as an array must have shape (N, 4), got {xyxy.shape}")
        n = xyxy.shape[0]
        return xyxy, ("object",) * n, np.full(n, -1, np.int64), np.ones(n, np.float32)
    # Foreign detection objects (not only detectors.Detections) are read by their attributes.
    for attr in ("xyxy", "confidence", "class_id"):
        if not hasattr(detections, attr):
            raise FusionInputError(
                "`detections` must be a detectors.Detections or an (N, 4) array of boxes, got "
                f"{type(detections).__name__}")
    xyxy = np.asarray(detections.xyxy, dtype=np.float64).reshape(-1, 4)
    n = xyxy.shape[0]
    labels = getattr(detections, "labels", None)
    if labels is None:
        names = getattr(detections, "class_names", ())
        labels = [names[c] if 0 <= c < len(names) else str(c) for c in np.asarray(detections.class_id)]
    return (xyxy, tuple(str(s) for s in labels), np.asarray(detections.class_id, np.int64).reshape(n),
            np.asarray(detections.confidence, np.float32).reshape(n))


def shrunk_pixel_box(box: np.ndarray, shrink: float, width: int, height: int) -> tuple[int, int, int, int]:
    """Integer pixel range [u0, u1) x [v0, v1) of the box scaled by (1 - shrink) about its centre, clipped.

    Parameters
    ----------
    box : (4,) float, pixels
        (x0, y0, x1, y1).
    shrink : float in [0, 1)
        Fraction of the width and height removed, half on each side.
    width, height : int
        Image size the range is clipped to.

    Returns
    -------
    (u0, v0, u1, v1) : int
        Empty (``u1 <= u0`` or ``v1 <= v0``) when nothing of the box is left inside the image.

    Examples
    --------
    >>> shrunk_pixel_box(np.array([10.0, 0.0, 30.0, 10.0]), 0.2, 100, 100)
    (12, 1, 28, 9)
    """
    x0, y0, x1, y1 = box
    cx, cy = (x0 + x1) / 2.0, (y0 + y1) / 2.0
    hw, hh = (x1 - x0) * (1.0 - shrink) / 2.0, (y1 - y0) * (1.0 - shrink) / 2.0
    u0 = int(np.clip(np.floor(cx - hw + 0.5), 0, width))
    u1 = int(np.clip(np.floor(cx + hw + 0.5), 0, width))
    v0 = int(np.clip(np.floor(cy - hh + 0.5), 0, height))
    v1 = int(np.clip(np.floor(cy + hh + 0.5), 0, height))
    return u0, v0, u1, v1
