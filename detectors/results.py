"""``Detections``: the result of one detector run, boxes in original-image pixels."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from detectors.classes import COCO_CATEGORY_IDS, COCO_CLASSES, coerce_names

__all__ = ["Detections"]


def _as_array(value: object, name: str) -> np.ndarray:
    try:
        return np.asarray(value)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"`{name}` must be array-like, got {type(value).__name__} ({exc})") from None


@dataclass(frozen=True, eq=False)
class Detections:
    """Detected objects of one image.

    Parameters
    ----------
    xyxy : (N, 4) float32
        Boxes ``x1, y1, x2, y2`` in pixels of the original image (x right, y down, edges, not centres),
        finite, ``x1 <= x2`` and ``y1 <= y2``.
    confidence : (N,) float32
        Score in ``[0, 1]``.
    class_id : (N,) int64
        Index into ``class_names``.
    class_names : tuple of str
        Name of every class the model knows (COCO-80 by default).

    Arrays are copied, converted to the dtypes above and made read-only. Filter with a boolean mask,
    an index array, a slice or an int (``dets[dets.confidence > 0.5]``) or by name (``dets.only("car")``).

    Examples
    --------
    >>> d = Detections(np.array([[10, 20, 50, 80]]), np.array([0.9]), np.array([2]))
    >>> d.labels
    ['car']
    """

    xyxy: np.ndarray
    confidence: np.ndarray
    class_id: np.ndarray
    class_names: tuple[str, ...] = field(default=COCO_CLASSES)

    def __post_init__(self) -> None:
        names = coerce_names(self.class_names, parameter="class_names")
        xyxy = _as_array(self.xyxy, "xyxy")
        conf = _as_array(self.confidence, "confidence")
        cid = _as_array(self.class_id, "class_id")
        if xyxy.size == 0 and xyxy.ndim <= 2:
            xyxy = xyxy.reshape(0, 4)
        if xyxy.ndim != 2 or xyxy.shape[1] != 4:
            raise ValueError(f"`xyxy` must have shape (N, 4), got {xyxy.shape}")
        n = xyxy.shape[0]
        if conf.shape != (n,):
            raise ValueError(f"`confidence` must have shape ({n},) to match `xyxy`, got {conf.shape}")
        if cid.shape != (n,):
            raise ValueError(f"`class_id` must have shape ({n},) to match `xyxy`, got {cid.shape}")
        for arr, name in ((xyxy, "xyxy"), (conf, "confidence")):
            if n and not (np.issubdtype(arr.dtype, np.floating) or np.issubdtype(arr.dtype, np.integer)):
                raise ValueError(f"`{name}` must be a real-valued array, got dtype {arr.dtype}")
        if n and not np.issubdtype(cid.dtype, np.integer):
            raise ValueError(f"`class_id` must be an integer array, got dtype {cid.dtype}")
        with np.errstate(over="ignore", invalid="ignore"):
            xyxy = np.array(xyxy, dtype=np.float32, copy=True)
            conf = np.array(conf, dtype=np.float32, copy=True)
        cid = np.array(cid, dtype=np.int64, copy=True)
        if not np.all(np.isfinite(xyxy)):
            raise ValueError("`xyxy` must be finite, got NaN or inf (or a value beyond float32)")
        if np.any(xyxy[:, 2] < xyxy[:, 0]) or np.any(xyxy[:, 3] < xyxy[:, 1]):
            bad = int(np.flatnonzero((xyxy[:, 2] < xyxy[:, 0]) | (xyxy[:, 3] < xyxy[:, 1]))[0])
            raise ValueError(f"`xyxy` rows must have x1 <= x2 and y1 <= y2, got row {bad}: {xyxy[bad].tolist()}")
        if not np.all((conf >= 0.0) & (conf <= 1.0)):  # also rejects NaN
            bad = conf[~((conf >= 0.0) & (conf <= 1.0))][0]
            raise ValueError(f"`confidence` must lie in [0, 1], got {float(bad)}")
        if n and (cid.min() < 0 or cid.max() >= len(names)):
            bad = int(cid[(cid < 0) | (cid >= len(names))][0])
            raise ValueError(f"`class_id` must lie in [0, {len(names) - 1}] (len(class_names) = {len(names)}), got {bad}")
        for arr in (xyxy, conf, cid):
            arr.flags.writeable = False
        object.__setattr__(self, "xyxy", xyxy)
        object.__setattr__(self, "confidence", conf)
        object.__setattr__(self, "class_id", cid)
        object.__setattr__(self, "class_names", names)

    # ------------------------------------------------------------------ construction
    @classmethod
    def empty(cls, class_names: Sequence[str] = COCO_CLASSES) -> Detections:
        """No detections (``len() == 0``) with the given class names."""
        return cls(np.zeros((0, 4), np.float32), np.zeros(0, np.float32), np.zeros(0, np.int64), tuple(class_names))

    # ------------------------------------------------------------------ access
    def __len__(self) -> int:
        return int(self.xyxy.shape[0])

    def __repr__(self) -> str:
        body = ", ".join(f"{lab} {c:.2f}" for lab, c in zip(self.labels[:5], self.confidence[:5].tolist()))
        more = ", ..." if len(self) > 5 else ""
        return f"Detections(n={len(self)}: {body}{more})"

    def __getitem__(self, index: object) -> Detections:
        """Subset by boolean mask (N,), integer index array, slice or int; returns new ``Detections``."""
        if isinstance(index, (int, np.integer)) and not isinstance(index, bool):
            n = len(self)
            if not -n <= int(index) < n:
                raise IndexError(f"detection index {int(index)} out of range for {n} detections")
            index = [int(index)]
        elif isinstance(index, slice):
            pass
        else:
            idx = np.asarray(index)
            if idx.dtype == np.bool_:
                if idx.shape != (len(self),):
                    raise IndexError(f"boolean mask must have shape ({len(self)},), got {idx.shape}")
            elif idx.size == 0:
                idx = idx.astype(np.int64)
            elif not np.issubdtype(idx.dtype, np.integer) or idx.ndim != 1:
                raise IndexError(f"index must be a boolean mask, 1-D integer array, slice or int; got {idx.dtype} {idx.shape}")
            index = idx
        return Detections(self.xyxy[index], self.confidence[index], self.class_id[index], self.class_names)

    @property
    def labels(self) -> list[str]:
        """Class name of every detection, in order."""
        return [self.class_names[i] for i in self.class_id.tolist()]

    def only(self, *names: str) -> Detections:
        """The detections whose class is one of ``names`` (``dets.only("person", "car")``).

        Raises ``ValueError`` naming an unknown class and listing the valid ones.
        """
        if not names:
            raise ValueError("`only` needs at least one class name, e.g. dets.only('person')")
        wanted = []
        for name in names:
            ids = [i for i, known in enumerate(self.class_names) if known == name]
            if not ids:
                raise ValueError(f"unknown class name {name!r}; valid names: {', '.join(self.class_names)}")
            wanted.extend(ids)
        return self[np.isin(self.class_id, wanted)]

    # ------------------------------------------------------------------ export
    def _category_ids(self) -> list[int]:
        if self.class_names == COCO_CLASSES:
            return [COCO_CATEGORY_IDS[i] for i in self.class_id.tolist()]
        return [i + 1 for i in self.class_id.tolist()]

    def to_coco(self, image_id: int) -> list[dict]:
        """COCO results format: ``{"image_id", "category_id", "bbox": [x, y, w, h], "score"}`` per box.

        ``category_id`` is the official COCO id when the class names are COCO-80 (``person`` -> 1,
        ``toothbrush`` -> 90), else ``class_id + 1``. All numbers are Python ints/floats.
        """
        if isinstance(image_id, bool) or not isinstance(image_id, (int, np.integer)):
            raise ValueError(f"`image_id` must be an int, got {image_id!r}")
        out = []
        for (x1, y1, x2, y2), score, cat in zip(self.xyxy.tolist(), self.confidence.tolist(), self._category_ids()):
            out.append({"image_id": int(image_id), "category_id": int(cat),
                        "bbox": [x1, y1, x2 - x1, y2 - y1], "score": score})
        return out

    def to_json(self) -> list[dict]:
        """Plain JSON-able list: ``{"class_id", "class_name", "confidence", "xyxy": [x1, y1, x2, y2]}``.

        Numbers are real JSON numbers (Python float/int), pixels of the original image.
        """
        return [
            {"class_id": cid, "class_name": self.class_names[cid], "confidence": conf, "xyxy": box}
            for box, conf, cid in zip(self.xyxy.tolist(), self.confidence.tolist(), self.class_id.tolist())
        ]
