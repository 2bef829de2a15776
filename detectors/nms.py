"""Class-aware non-maximum suppression (greedy, vectorised numpy) and box IoU."""

from __future__ import annotations

import numpy as np

__all__ = ["nms", "box_iou"]


def box_iou(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """IoU of every box in ``a`` (N, 4) with every box in ``b`` (M, 4), xyxy; returns (N, M) float64.

    Boxes of zero area have IoU 0 with everything (no division by zero).
    """
    a = np.asarray(a, dtype=np.float64).reshape(-1, 4)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 4)
    iw = np.minimum(a[:, None, 2], b[None, :, 2]) - np.maximum(a[:, None, 0], b[None, :, 0])
    ih = np.minimum(a[:, None, 3], b[None, :, 3]) - np.maximum(a[:, None, 1], b[None, :, 1])
    inter = np.clip(iw, 0, None) * np.clip(ih, 0, None)
    area_a = (a[:, 2] - a[:, 0]) * (a[:, 3] - a[:, 1])
    area_b = (b[:, 2] - b[:, 0]) * (b[:, 3] - b[:, 1])
    union = area_a[:, None] + area_b[None, :] - inter
    return np.divide(inter, union, out=np.zeros_like(inter), where=union > 0)


def nms(
    xyxy: np.ndarray,
    scores: np.ndarray,
    class_id: np.ndarray | None = None,
    *,
    iou_threshold: float = 0.45,
    max_detections: int | None = None,
) -> np.ndarray:
    """Greedy non-maximum suppression, per class when ``class_id`` is given.

    Parameters
    ----------
    xyxy : (N, 4) float
        Boxes, ``x1 <= x2``, ``y1 <= y2``, finite.
    scores : (N,) float
        Higher is better; ties keep the earlier box.
    class_id : (N,) int, optional
        Boxes of different classes never suppress each other. None: class-agnostic.
    iou_threshold : float in [0, 1]
        A box is dropped when its IoU with a kept, higher-scored box of its class is above this.
    max_detections : int, optional
        Keep at most this many (the highest scored).

    Returns
    -------
    keep : (K,) int64
        Indices into the input, highest score first.
    """
    boxes = np.asarray(xyxy, dtype=np.float64)
    scores = np.asarray(scores, dtype=np.float64)
    if boxes.ndim != 2 or boxes.shape[1] != 4:
        raise ValueError(f"`xyxy` must have shape (N, 4), got {boxes.shape}")
    n = boxes.shape[0]
    if scores.shape != (n,):
        raise ValueError(f"`scores` must have shape ({n},), got {scores.shape}")
    if not np.all(np.isfinite(boxes)) or not np.all(np.isfinite(scores)):
        raise ValueError("`xyxy` and `scores` must be finite, got NaN or inf")
    if np.any(boxes[:, 2] < boxes[:, 0]) or np.any(boxes[:, 3] < boxes[:, 1]):
        raise ValueError("`xyxy` rows must have x1 <= x2 and y1 <= y2")
    if isinstance(iou_threshold, bool) or not isinstance(iou_threshold, (int, float, np.floating)) \
            or not 0.0 <= float(iou_threshold) <= 1.0:
        raise ValueError(f"`iou_threshold` must be a number in [0, 1], got {iou_threshold!r}")
    if max_detections is not None and (isinstance(max_detections, bool) or not isinstance(max_detections, (int, np.integer))
                                       or max_detections < 0):
        raise ValueError(f"`max_detections` must be a non-negative int or None, got {max_detections!r}")
    if class_id is not None:
        cls = np.asarray(class_id)
        if cls.shape != (n,) or (n and not np.issubdtype(cls.dtype, np.integer)):
            raise ValueError(f"`class_id` must be an integer array of shape ({n},), got {cls.dtype} {cls.shape}")
    else:
        cls = np.zeros(n, np.int64)
    limit = n if max_detections is None else int(max_detections)
    order = np.argsort(-scores, kind="stable")
    thr = float(iou_threshold)
    keep: list[int] = []
    while order.size and len(keep) < limit:
        i = int(order[0])
        keep.append(i)
        rest = order[1:]
        if not rest.size:
            break
        iou = box_iou(boxes[i:i + 1], boxes[rest])[0]
        order = rest[(iou <= thr) | (cls[rest] != cls[i])]
    return np.asarray(keep, dtype=np.int64)
