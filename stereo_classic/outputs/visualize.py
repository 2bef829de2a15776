"""Pictures for people: colour-mapped disparity/depth and labelled boxes.

Example
-------
>>> import numpy as np
>>> from stereo_classic.outputs import colorize, draw_boxes
>>> disparity = np.array([[1.0, 2.0], [np.nan, 4.0]], dtype=np.float32)
>>> colorize(disparity)[1, 0].tolist()   # unknown -> black
[0, 0, 0]
>>> image = np.zeros((60, 80, 3), np.uint8)
>>> draw_boxes(image, [[10, 20, 50, 55]], ["car 12.4 m"]).shape
(60, 80, 3)
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np

__all__ = ["PALETTE", "colorize", "draw_boxes", "place_labels"]

#: Largest ``thickness`` / ``font_scale`` :func:`draw_boxes` accepts (OpenCV fails or stalls far beyond).
MAX_THICKNESS = 64
MAX_FONT_SCALE = 32.0

#: BGR colours used for boxes when none are given (cycled by box index).
PALETTE: tuple[tuple[int, int, int], ...] = (
    (56, 56, 255), (151, 157, 255), (31, 112, 255), (29, 178, 255), (49, 210, 207),
    (10, 249, 72), (23, 204, 146), (134, 219, 61), (52, 147, 26), (187, 212, 0),
    (168, 153, 44), (255, 194, 0), (147, 69, 52), (255, 115, 100), (236, 24, 0),
    (255, 56, 132), (133, 0, 82), (255, 56, 203), (200, 149, 255), (199, 55, 255),
)  # fmt: skip


def _check_color(value: Any, name: str) -> tuple[int, int, int]:
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"`{name}` must be three integers 0..255 (B, G, R), got {value!r}") from None
    if arr.shape != (3,) or not np.isfinite(arr).all() or (arr < 0).any() or (arr > 255).any():
        raise ValueError(f"`{name}` must be three integers 0..255 (B, G, R), got {value!r}")
    c = tuple(int(round(v)) for v in arr)
    return c  # type: ignore[return-value]


def _check_limit(value: Any, name: str) -> float | None:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise TypeError(f"`{name}` must be a number or None, got {type(value).__name__}")
    v = float(value)
    if not np.isfinite(v):
        raise ValueError(f"`{name}` must be finite, got {value}")
    return v


def colorize(
    values: np.ndarray,
    *,
    vmin: float | None = None,
    vmax: float | None = None,
    invalid_color: Sequence[int] = (0, 0, 0),
) -> np.ndarray:
    """Colour-map a disparity or depth map with TURBO (blue = low, red = high).

    Parameters
    ----------
    values : (H, W) real array
        Disparity (px) or depth (m); NaN and +-inf are drawn in ``invalid_color``.
    vmin, vmax : float, optional, keyword-only
        Values mapped to the ends of the colour map (values outside are clipped). When not given, the
        1st and 99th percentiles of the finite values are used, so a few outliers do not wash out the
        picture.
    invalid_color : (B, G, R), keyword-only
        Colour of unknown pixels, black by default.

    Returns
    -------
    image : (H, W, 3) uint8 BGR
    """
    if not isinstance(values, np.ndarray):
        raise TypeError(f"`values` must be a numpy array, got {type(values).__name__}")
    if values.dtype == bool or not (
        np.issubdtype(values.dtype, np.integer) or np.issubdtype(values.dtype, np.floating)
    ):
        raise ValueError(f"`values` must be a real integer or floating array, got dtype {values.dtype}")
    if values.ndim != 2 or values.shape[0] == 0 or values.shape[1] == 0:
        raise ValueError(f"`values` must be a non-empty (H, W) array, got shape {values.shape}")
    bad_color = _check_color(invalid_color, "invalid_color")
    lo, hi = _check_limit(vmin, "vmin"), _check_limit(vmax, "vmax")
    if lo is not None and hi is not None and lo > hi:
        raise ValueError(f"`vmin` must be <= `vmax`, got vmin={lo}, vmax={hi}")
    v = values.astype(np.float64, copy=False)
    valid = np.isfinite(v)
    out = np.empty(v.shape + (3,), dtype=np.uint8)
    out[...] = bad_color
    if not valid.any():
        return out
    finite = v[valid]
    if lo is None or hi is None:
        p_lo, p_hi = np.percentile(finite, [1.0, 99.0])
        lo = float(p_lo) if lo is None else lo
        hi = float(p_hi) if hi is None else hi
        if lo > hi:  # one limit given, the percentile on the other side of it
            lo, hi = (hi, hi) if vmin is None else (lo, lo)
    span = hi - lo
    if span > 0:
        norm = np.clip((finite - lo) / span, 0.0, 1.0)
    else:
        norm = np.full(finite.shape, 0.5)
    index = np.rint(norm * 255.0).astype(np.uint8)
    colors = cv2.applyColorMap(index.reshape(-1, 1), cv2.COLORMAP_TURBO).reshape(-1, 3)
    out[valid] = colors
    return out


def _text_color(bg: tuple[int, int, int]) -> tuple[int, int, int]:
    b, g, r = bg
    luminance = 0.114 * b + 0.587 * g + 0.299 * r
    return (0, 0, 0) if luminance > 140 else (255, 255, 255)


def draw_boxes(
    image: np.ndarray,
    xyxy: Any,
    labels: Sequence[str] | None = None,
    *,
    colors: Sequence[int] | Sequence[Sequence[int]] | None = None,
    thickness: int | None = None,
    font_scale: float | None = None,
) -> np.ndarray:
    """Draw boxes with labels such as ``"car 12.4 m"`` on a copy of ``image``.

    Each label sits on a filled background in the box colour (text black or white, whichever reads
    better), above the box when there is room, else inside or below it; no label covers another
    (:func:`place_labels`), and labels are drawn after every box line.

    Parameters
    ----------
    image : (H, W, 3) BGR or (H, W) grey, uint8
        Not modified; grey images are returned as BGR.
    xyxy : (N, 4) array-like, pixels
        x1, y1, x2, y2 per box (x1 <= x2, y1 <= y2). Boxes are clipped to the image.
    labels : sequence of N str, optional
        Text per box; None or "" draws no label.
    colors : (B, G, R) or N of them, optional, keyword-only
        One colour for all boxes or one per box; default: a fixed palette by box index.
    thickness, font_scale : keyword-only
        Line thickness (px, int in [1, 64]) and OpenCV font scale (in (0, 32]); default from the image size.

    Returns
    -------
    image : (H, W, 3) uint8 BGR, a new array.
    """
    if not isinstance(image, np.ndarray):
        raise TypeError(f"`image` must be a numpy array, got {type(image).__name__}")
    if image.dtype != np.uint8:
        raise ValueError(f"`image` must have dtype uint8, got {image.dtype}")
    if image.ndim == 2:
        canvas = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    elif image.ndim == 3 and image.shape[2] == 3:
        canvas = image.copy()
    else:
        raise ValueError(f"`image` must have shape (H, W) or (H, W, 3), got {image.shape}")
    if canvas.shape[0] == 0 or canvas.shape[1] == 0:
        raise ValueError(f"`image` must not be empty, got shape {image.shape}")
    try:
        boxes = np.asarray(xyxy, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("`xyxy` must be an (N, 4) array of numbers") from None
    if boxes.size == 0:
        boxes = boxes.reshape(0, 4)
    if boxes.ndim != 2 or boxes.shape[1] != 4:
        raise ValueError(f"`xyxy` must have shape (N, 4), got {boxes.shape}")
    if not np.isfinite(boxes).all():
        raise ValueError("`xyxy` must be finite, got NaN or inf")
    if (boxes[:, 2] < boxes[:, 0]).any() or (boxes[:, 3] < boxes[:, 1]).any():
        raise ValueError("`xyxy` boxes must have x1 <= x2 and y1 <= y2")
    n = boxes.shape[0]
    if labels is None:
        texts = [""] * n
    else:
        if isinstance(labels, str):
            raise TypeError("`labels` must be a sequence of strings, got a single str")
        texts = ["" if t is None else str(t) for t in labels]
        if len(texts) != n:
            raise ValueError(f"`labels` must have one entry per box ({n}), got {len(texts)}")
    if colors is None:
        box_colors = [PALETTE[i % len(PALETTE)] for i in range(n)]
    else:
        try:
            carr = np.asarray(colors, dtype=np.float64)
        except (TypeError, ValueError):
            raise ValueError(f"`colors` must be one (B, G, R) or an (N, 3) array, got {colors!r}") from None
        if carr.shape == (3,):
            box_colors = [_check_color(carr, "colors")] * n
        elif carr.shape == (n, 3):
            box_colors = [_check_color(c, f"colors[{i}]") for i, c in enumerate(carr)]
        else:
            raise ValueError(f"`colors` must be one (B, G, R) or one per box, shape ({n}, 3), got shape {carr.shape}")
    h, w = canvas.shape[:2]
    if font_scale is None:
        scale = min(MAX_FONT_SCALE, max(0.4, min(h, w) / 800.0))
    else:
        if isinstance(font_scale, bool) or not isinstance(font_scale, (int, float, np.integer, np.floating)) or not (
            np.isfinite(font_scale) and 0 < font_scale <= MAX_FONT_SCALE
        ):
            raise ValueError(f"`font_scale` must be a positive finite number <= {MAX_FONT_SCALE}, got {font_scale!r}")
        scale = float(font_scale)
    if thickness is None:
        line = min(MAX_THICKNESS, max(1, round(min(h, w) / 300)))
    else:
        if isinstance(thickness, bool) or not isinstance(thickness, (int, np.integer)) or not (
            1 <= thickness <= MAX_THICKNESS
        ):
            raise ValueError(f"`thickness` must be an int in [1, {MAX_THICKNESS}], got {thickness!r}")
        line = int(thickness)
    font = cv2.FONT_HERSHEY_SIMPLEX
    text_thickness = max(1, line // 2)
    pad = 2
    clipped = []
    for (x1, y1, x2, y2), color in zip(boxes, box_colors):
        p1 = (int(np.clip(round(x1), 0, w - 1)), int(np.clip(round(y1), 0, h - 1)))
        p2 = (int(np.clip(round(x2), 0, w - 1)), int(np.clip(round(y2), 0, h - 1)))
        cv2.rectangle(canvas, p1, p2, color, line, cv2.LINE_8)
        clipped.append((*p1, *p2))
    # labels after every box, so no box line crosses a label; placed so that no label covers another
    metrics = [cv2.getTextSize(t, font, scale, text_thickness) if t else ((0, 0), 0) for t in texts]
    sizes = [(tw + 2 * pad, th + base + 2 * pad) if t else (0, 0) for t, ((tw, th), base) in zip(texts, metrics)]
    for text, color, size, (left, top), ((_, th), _) in zip(texts, box_colors, sizes,
                                                          place_labels(clipped, sizes, (w, h)), metrics):
        if not text:
            continue
        cv2.rectangle(canvas, (left, top), (left + size[0] - 1, top + size[1] - 1), color, cv2.FILLED)
        cv2.putText(canvas, text, (left + pad, top + pad + th), font, scale, _text_color(color),
                    text_thickness, cv2.LINE_AA)
    return canvas


def _overlaps(a: tuple[int, int, int, int], b: tuple[int, int, int, int]) -> bool:
    return a[0] < b[0] + b[2] and b[0] < a[0] + a[2] and a[1] < b[1] + b[3] and b[1] < a[1] + a[3]


def _free(rect: tuple[int, int, int, int], placed: Sequence[tuple[int, int, int, int]]) -> bool:
    return not any(_overlaps(rect, r) for r in placed)


def place_labels(boxes: Sequence[Sequence[int]], sizes: Sequence[tuple[int, int]], image_size: tuple[int, int]
                 ) -> list[tuple[int, int]]:
    """Top-left corners for box labels such that no label covers another.

    Each label goes to the first free place among: above its box, inside its top edge, below it, inside its
    bottom edge; then to the nearest free row beside the box's left edge; then anywhere free in the image.
    Only a picture too small to hold every label side by side makes labels overlap.

    Parameters
    ----------
    boxes : N boxes (x1, y1, x2, y2), pixels inside the image
    sizes : N (width, height) of the labels in pixels; (0, 0) for a box without a label
    image_size : (width, height)

    Returns
    -------
    list of N (left, top), pixels

    >>> place_labels([(10, 40, 50, 80), (10, 40, 50, 80)], [(30, 12), (30, 12)], (100, 100))
    [(10, 28), (10, 40)]
    """
    w, h = int(image_size[0]), int(image_size[1])
    placed: list[tuple[int, int, int, int]] = []
    out = []
    for box, (lw, lh) in zip(boxes, sizes):
        x1, y1, _, y2 = (int(v) for v in box)
        if lw <= 0 or lh <= 0:
            out.append((x1, y1))
            continue
        max_left, max_top = max(0, w - lw), max(0, h - lh)
        left = min(x1, max_left)
        candidates = [(left, y) for y in (y1 - lh, y1, y2 + 1, y2 - lh + 1) if 0 <= y <= max_top]
        spot = next(((x, y) for x, y in candidates if _free((x, y, lw, lh), placed)), None)
        if spot is None:  # the nearest free row at the box's left edge, then anywhere
            rows = sorted(range(max_top + 1), key=lambda y, top=y1 - lh: abs(y - top))
            spot = next(((left, y) for y in rows if _free((left, y, lw, lh), placed)), None)
        if spot is None:
            spot = next(((x, y) for y in range(max_top + 1) for x in range(0, max_left + 1, max(1, lw // 4))
                         if _free((x, y, lw, lh), placed)), (left, min(max(y1, 0), max_top)))
        placed.append((spot[0], spot[1], lw, lh))
        out.append((int(spot[0]), int(spot[1])))
    return out
