"""Class names: COCO-80, the COCO category ids, and class names stored in ONNX metadata or files."""

from __future__ import annotations

import ast
import os
from collections.abc import Mapping, Sequence
from pathlib import Path

from detectors.errors import ModelError

__all__ = ["COCO_CLASSES", "COCO_CATEGORY_IDS", "names_from_metadata", "read_names_file", "coerce_names"]

COCO_CLASSES: tuple[str, ...] = (
    "person", "bicycle", "car", "motorcycle", "airplane", "bus", "train", "truck", "boat",
    "traffic light", "fire hydrant", "stop sign", "parking meter", "bench", "bird", "cat", "dog",
    "horse", "sheep", "cow", "elephant", "bear", "zebra", "giraffe", "backpack", "umbrella",
    "handbag", "tie", "suitcase", "frisbee", "skis", "snowboard", "sports ball", "kite",
    "baseball bat", "baseball glove", "skateboard", "surfboard", "tennis racket", "bottle",
    "wine glass", "cup", "fork", "knife", "spoon", "bowl", "banana", "apple", "sandwich", "orange",
    "broccoli", "carrot", "hot dog", "pizza", "donut", "cake", "chair", "couch", "potted plant",
    "bed", "dining table", "toilet", "tv", "laptop", "mouse", "remote", "keyboard", "cell phone",
    "microwave", "oven", "toaster", "sink", "refrigerator", "book", "clock", "vase", "scissors",
    "teddy bear", "hair drier", "toothbrush",
)  # fmt: skip
"""The 80 COCO detection classes in the order every COCO-trained YOLO/NanoDet model uses."""

COCO_CATEGORY_IDS: tuple[int, ...] = (
    1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24, 25, 27, 28,
    31, 32, 33, 34, 35, 36, 37, 38, 39, 40, 41, 42, 43, 44, 46, 47, 48, 49, 50, 51, 52, 53, 54, 55,
    56, 57, 58, 59, 60, 61, 62, 63, 64, 65, 67, 70, 72, 73, 74, 75, 76, 77, 78, 79, 80, 81, 82, 84,
    85, 86, 87, 88, 89, 90,
)  # fmt: skip
"""Official COCO category id of each of the 80 classes (``COCO_CATEGORY_IDS[class_id]``)."""


def coerce_names(names: object, *, parameter: str = "names") -> tuple[str, ...]:
    """Check and convert a sequence of class names (or an ``{index: name}`` mapping) to a tuple.

    A mapping must have the keys ``0 .. n-1``. Raises ``ValueError`` naming ``parameter``.
    """
    if isinstance(names, Mapping):
        try:
            keys = sorted(int(k) for k in names)
        except (TypeError, ValueError):
            raise ValueError(f"`{parameter}` mapping must have integer keys, got {list(names)[:5]!r}") from None
        if keys != list(range(len(keys))):
            raise ValueError(f"`{parameter}` mapping must have the keys 0..{len(keys) - 1}, got {keys[:10]!r}")
        lookup = {int(k): v for k, v in names.items()}
        names = [lookup[i] for i in range(len(keys))]
    if isinstance(names, (str, bytes)) or not isinstance(names, Sequence):
        raise ValueError(f"`{parameter}` must be a sequence of class names, got {type(names).__name__}")
    out = tuple(names)
    if not out:
        raise ValueError(f"`{parameter}` must hold at least one class name, got an empty sequence")
    for i, name in enumerate(out):
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"`{parameter}`[{i}] must be a non-empty string, got {name!r}")
    return out


def names_from_metadata(metadata: Mapping[str, str]) -> tuple[str, ...] | None:
    """Class names stored in ONNX metadata (ultralytics: ``names`` = ``"{0: 'person', ...}"``).

    Parsed with :func:`ast.literal_eval` (literals only, never code); a list string or a
    comma/newline separated string is accepted too. Returns None where there is no such key.
    Raises :class:`ModelError` when the value is there but unreadable.
    """
    for key in ("names", "classes", "labels", "class_names"):
        raw = metadata.get(key)
        if raw is None:
            continue
        raw = raw.strip()
        if len(raw) > 1_000_000:
            raise ModelError(f"ONNX metadata `{key}` is {len(raw)} characters long; not a list of class names")
        if raw[:1] in "{[(":
            try:
                value = ast.literal_eval(raw)
            except (ValueError, SyntaxError, MemoryError, RecursionError, TypeError) as exc:
                raise ModelError(f"ONNX metadata `{key}` is not a readable list or dict of class names ({exc})") from None
        else:
            sep = "\n" if "\n" in raw else ","
            value = [part.strip() for part in raw.split(sep) if part.strip()]
        try:
            return coerce_names(value, parameter=f"metadata {key}")
        except ValueError as exc:
            raise ModelError(f"ONNX metadata: {exc}") from None
    return None


def read_names_file(path: str | os.PathLike) -> tuple[str, ...]:
    """Class names from a text file, one name a line (blank lines ignored, order = class id)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"names file {path} does not exist")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"names file {path} is not UTF-8 text ({exc.reason})") from None
    names = [line.strip() for line in text.splitlines() if line.strip()]
    if not names:
        raise ValueError(f"names file {path} holds no class names")
    return tuple(names)
