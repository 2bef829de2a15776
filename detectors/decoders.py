"""Output layouts of exported detectors: how each is recognised and decoded.

Every decoder turns the raw ONNX outputs into candidate boxes ``xyxy`` (K, 4) float32 in
*model-input* pixels, ``scores`` (K,) float32 and ``class_id`` (K,) int64, already filtered by the
confidence threshold (and, for exports with NMS inside, already suppressed).

How the family is chosen (first rule that applies):

1. ``family=`` given by the caller.
2. Output names/shapes that only one family has:
   - NanoDet: pairs of outputs ``(1, n_i, C)`` class scores and ``(1, n_i, 4 * (R + 1))`` distance
     distributions per stride (names ``cls_pred_stride_8`` / ``dis_pred_stride_8``);
   - NMS included: ``boxes (1, K, 4)`` + ``scores (1, K)`` + ``classes (1, K)`` (+ ``num_dets``), or
     ``dets (1, K, 5)`` + ``labels (1, K)``, or one ``(1, K, 6)`` = x1, y1, x2, y2, score, class where
     ``K`` is not an anchor count of the input size (ultralytics ``nms=True`` / YOLOv10);
   - FastestDet: one ``(1, 5 + C, H/16, W/16)`` grid;
   - YOLOv8 / YOLO11: one ``(1, 4 + C, N)`` (channels first, N > 4 + C);
3. One ``(1, N, 5 + C)`` is YOLOX (raw) or YOLOv5 (decoded): ultralytics metadata (``stride`` /
   ``names``) -> YOLOv5; else the anchor count: YOLOX is anchor-free with one prediction per grid
   cell, ``N = sum_s (H/s)(W/s)`` over strides 8, 16, 32; YOLOv5 has 3 anchors per cell,
   ``N = 3 * sum_s (H/s)(W/s)`` (strides 8-32, or 8-64 for P6 models); where neither matches, the
   file name (``yolox`` / ``yolov5``/``yolov7``) decides; else :class:`ModelError`.
   A YOLOX exported with ``--decode_in_inference`` has the YOLOX count but decoded boxes: pass
   ``family="yolov5"`` for it (same N x 85 decoded layout, objectness x class).
4. ``(1, N, C + 4 * (R + 1))`` with the 4-level anchor-free count (strides 8-64) is NanoDet-Plus.
Anything else: :class:`ModelError` naming the shapes seen.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from detectors.errors import ModelError
from detectors.letterbox import Preprocessing

__all__ = ["FAMILIES", "PREPROCESSING", "OutputLayout", "recognise_layout", "decode", "grid_count"]

FAMILIES = ("yolox", "yolov5", "yolov8", "nanodet", "nanodet_plus", "fastestdet", "nms")

_ULTRALYTICS = Preprocessing(rgb=True, scale=1.0 / 255.0, pad_value=114.0, centre=True)
_NANODET = Preprocessing(rgb=False, mean=(103.53, 116.28, 123.675), std=(57.375, 57.12, 58.395),
                         pad_value=0.0, centre=True)
PREPROCESSING: dict[str, Preprocessing] = {
    # YOLOX (>= 0.1.1 exports): BGR 0-255 not normalised, top-left, grey 114 border.
    "yolox": Preprocessing(rgb=False, scale=1.0, pad_value=114.0, centre=False),
    "yolov5": _ULTRALYTICS,
    "yolov8": _ULTRALYTICS,
    "nms": _ULTRALYTICS,
    # NanoDet: BGR, (x - mean) / std with ImageNet statistics in BGR order, black border.
    "nanodet": _NANODET,
    "nanodet_plus": _NANODET,
    # FastestDet: plain resize to the input size, / 255.
    "fastestdet": Preprocessing(rgb=False, scale=1.0 / 255.0, keep_ratio=False),
}


@dataclass(frozen=True)
class OutputLayout:
    """A recognised output layout: which family decodes it and how the outputs are arranged."""

    family: str
    num_classes: int
    outputs: tuple[int, ...]          # indices into the session outputs, in the order the decoder wants
    strides: tuple[int, ...] = ()
    reg_max: int = 0
    extra: Mapping[str, object] = field(default_factory=dict)

    def describe(self) -> str:
        parts = [self.family, f"{self.num_classes} classes"]
        if self.strides:
            parts.append("strides " + "/".join(map(str, self.strides)))
        return ", ".join(parts)


def grid_count(height: int, width: int, strides: Sequence[int]) -> int:
    """Number of grid cells over all strides (``sum ceil(H/s) * ceil(W/s)``)."""
    return sum(math.ceil(height / s) * math.ceil(width / s) for s in strides)


def _fmt_shapes(names: Sequence[str], shapes: Sequence[tuple]) -> str:
    return ", ".join(f"{n} {tuple(s)}" for n, s in zip(names, shapes))


def _hint_from_name(hint: str) -> str | None:
    h = hint.lower()
    if "nanodet" in h and "plus" in h:
        return "nanodet_plus"
    for key, fam in (("yolox", "yolox"), ("yolov5", "yolov5"), ("yolov7", "yolov5"), ("nanodet", "nanodet"),
                     ("fastestdet", "fastestdet"), ("yolov8", "yolov8"), ("yolo11", "yolov8"), ("yolov11", "yolov8")):
        if key in h:
            return fam
    return None


def _is_ultralytics(metadata: Mapping[str, str]) -> bool:
    return "ultralytics" in metadata.get("author", "").lower() or ("stride" in metadata and "names" in metadata)


def recognise_layout(
    names: Sequence[str],
    shapes: Sequence[tuple[int, ...]],
    dtypes: Sequence[np.dtype],
    input_hw: tuple[int, int],
    *,
    metadata: Mapping[str, str] | None = None,
    hint: str = "",
    family: str | None = None,
    num_names: int | None = None,
) -> OutputLayout:
    """Choose the decoder for outputs of these ``shapes`` (actual shapes from a run, batch first).

    ``input_hw`` is the model input (height, width); ``hint`` a file name; ``num_names`` the number of
    class names known from metadata or the caller (used to check the class count).
    """
    metadata = metadata or {}
    if family is not None and family not in FAMILIES:
        raise ValueError(f"`family` must be one of {', '.join(FAMILIES)} or None, got {family!r}")
    shapes = [tuple(int(d) for d in s) for s in shapes]
    seen = _fmt_shapes(names, shapes)
    H, W = input_hw

    def fail(why: str) -> ModelError:
        return ModelError(f"unrecognised detector output layout ({why}); outputs: {seen}; input {H}x{W}. "
                          f"Known: {', '.join(FAMILIES)}; pass family=... if the model is one of them")

    fam = family
    # --- several outputs: NanoDet pairs or NMS-included
    if len(shapes) > 1:
        if fam in (None, "nanodet"):
            layout = _try_nanodet(names, shapes, input_hw, num_names)
            if layout is not None:
                return layout
            if fam == "nanodet":
                raise fail("family='nanodet' needs pairs of (1, n, C) class and (1, n, 4*(R+1)) distance outputs")
        if fam in (None, "nms"):
            layout = _try_nms_multi(names, shapes, dtypes, num_names)
            if layout is not None:
                return layout
            if fam == "nms":
                raise fail("family='nms' needs boxes (1, K, 4), scores (1, K) and classes (1, K) outputs")
        if fam is None:
            # e.g. older YOLOv5 exports: the combined (1, N, 85) output first, then one raw output per level
            try:
                return recognise_layout(names[:1], shapes[:1], dtypes[:1], input_hw, metadata=metadata, hint=hint,
                                        num_names=num_names)
            except ModelError:
                raise fail(f"{len(shapes)} outputs match neither NanoDet nor an export with NMS, "
                           "and the first output alone is no known layout") from None
        # a single-output family named with extra outputs: decode the first output
    shape = shapes[0]
    if len(shape) == 4 and shape[0] == 1 and fam in (None, "fastestdet"):
        c, gh, gw = shape[1:]
        if c > 5 and gh == math.ceil(H / 16) and gw == math.ceil(W / 16):
            return OutputLayout("fastestdet", c - 5, (0,), strides=(16,))
        if fam == "fastestdet":
            raise fail(f"family='fastestdet' needs (1, 5 + C, {math.ceil(H / 16)}, {math.ceil(W / 16)})")
    if len(shape) == 3 and shape[0] == 1:
        shape = shape[1:]
    if len(shape) != 2:
        raise fail("expected one (1, N, K) or (1, K, N) output")
    a, b = shape
    if fam == "nms" or (fam is None and b in (6, 7) and a not in _anchor_counts(H, W)):
        if b == 6:
            return OutputLayout("nms", num_names or 80, (0,), extra={"kind": "xyxy_score_class"})
        if b == 7:
            return OutputLayout("nms", num_names or 80, (0,), extra={"kind": "batch_xyxy_class_score"})
        raise fail("family='nms' with one output needs (K, 6) x1, y1, x2, y2, score, class")
    if fam == "yolov8" or (fam is None and a < b):
        c = a - 4
        if c < 1:
            raise fail("channels-first output with fewer than 5 rows")
        return OutputLayout("yolov8", c, (0,), extra={"transposed": a < b})
    n, k = a, b
    if fam in (None, "nanodet_plus") and k > 8 and n == grid_count(H, W, (8, 16, 32, 64)):
        for reg_max in (7, 15, 16, 10):
            c = k - 4 * (reg_max + 1)
            if c >= 1 and (num_names is None or c == num_names):
                return OutputLayout("nanodet_plus", c, (0,), strides=(8, 16, 32, 64), reg_max=reg_max)
        if fam == "nanodet_plus":
            raise fail("cannot split the last dimension into C classes + 4*(R+1) distance bins")
    if k < 6:
        raise fail(f"(N, {k}) rows are too short for xywh + objectness + classes")
    if fam is None:
        yolox_n = grid_count(H, W, (8, 16, 32))
        if _is_ultralytics(metadata):
            fam = "yolov5"
        elif n == yolox_n:
            fam = "yolox"
        elif n in (3 * yolox_n, 3 * grid_count(H, W, (8, 16, 32, 64))):
            fam = "yolov5"
        else:
            fam = _hint_from_name(hint)
            if fam not in ("yolox", "yolov5"):
                raise fail(f"(N={n}, {k}) rows: N is neither the YOLOX count {yolox_n} nor the YOLOv5 count "
                           f"{3 * yolox_n} for this input size, and no metadata or file name says which")
    if fam == "yolox":
        strides = (8, 16, 32)
        if n != grid_count(H, W, strides):
            raise fail(f"YOLOX raw output needs N = {grid_count(H, W, strides)} grid cells "
                       f"(strides 8/16/32, ceil(H/s) x ceil(W/s) each), got {n}")
        return OutputLayout("yolox", k - 5, (0,), strides=strides)
    if fam == "yolov5":
        return OutputLayout("yolov5", k - 5, (0,))
    raise fail(f"family {fam!r} does not fit a single {shapes[0]} output")


def _anchor_counts(H: int, W: int) -> set[int]:
    g3 = grid_count(H, W, (8, 16, 32))
    return {g3, 3 * g3, 3 * grid_count(H, W, (8, 16, 32, 64)), grid_count(H, W, (8, 16, 32, 64))}


def _try_nanodet(names, shapes, input_hw, num_names) -> OutputLayout | None:
    H, W = input_hw
    if len(shapes) % 2 or any(len(s) != 3 or s[0] != 1 for s in shapes):
        return None
    groups: dict[int, list[int]] = {}
    for i, s in enumerate(shapes):
        groups.setdefault(s[1], []).append(i)
    if any(len(g) != 2 for g in groups.values()):
        return None
    stride_of = {}
    for s in (8, 16, 32, 64, 128):
        stride_of.setdefault(math.ceil(H / s) * math.ceil(W / s), s)
    order: list[int] = []
    strides: list[int] = []
    num_classes = reg_bins = None
    for n in sorted(groups, reverse=True):
        pair = _order_pair(groups[n], names, shapes, num_names)
        if pair is None:
            return None
        i, j = pair
        c, d = shapes[i][2], shapes[j][2]
        if d % 4 or d < 8 or n not in stride_of:
            return None
        m = re.search(r"stride_?(\d+)", names[i])
        stride = int(m.group(1)) if m else stride_of[n]
        if math.ceil(H / stride) * math.ceil(W / stride) != n:
            return None
        if num_classes not in (None, c) or reg_bins not in (None, d):
            return None
        num_classes, reg_bins = c, d
        order += [i, j]
        strides.append(stride)
    return OutputLayout("nanodet", int(num_classes), tuple(order), strides=tuple(strides), reg_max=reg_bins // 4 - 1)


def _order_pair(pair, names, shapes, num_names) -> tuple[int, int] | None:
    """(class-score output, distance output) of one NanoDet level, from names, else from the class count."""
    def is_cls(i):
        return any(w in names[i].lower() for w in ("cls", "score"))

    def is_dis(i):
        return any(w in names[i].lower() for w in ("dis", "reg", "box", "bbox"))

    i, j = pair
    for a, b in ((i, j), (j, i)):
        if (is_cls(a) and not is_cls(b)) or (is_dis(b) and not is_dis(a)):
            return a, b
    if num_names is not None:
        fits = [k for k in pair if shapes[k][2] == num_names]
        if len(fits) == 1:
            return fits[0], j if fits[0] == i else i
    return None


def _try_nms_multi(names, shapes, dtypes, num_names) -> OutputLayout | None:
    squeezed = [s[1:] if len(s) >= 2 and s[0] == 1 else s for s in shapes]
    lower = [n.lower() for n in names]
    box_idx = [i for i, s in enumerate(squeezed) if len(s) == 2 and s[1] in (4, 5)]
    if len(box_idx) != 1:
        return None
    bi = box_idx[0]
    k = squeezed[bi][0]
    vec = [i for i, s in enumerate(squeezed) if i != bi and s == (k,)]
    count = [i for i, s in enumerate(squeezed) if i != bi and i not in vec and int(np.prod(s)) == 1]
    if squeezed[bi][1] == 5:  # dets (K, 5) + labels (K,)
        if len(vec) != 1:
            return None
        return OutputLayout("nms", num_names or 80, (bi, vec[0], vec[0]), extra={"kind": "dets_labels"})
    if len(vec) != 2:
        return None
    si, ci = vec
    if any(w in lower[si] for w in ("class", "label", "cls")) or np.issubdtype(dtypes[si], np.integer):
        si, ci = ci, si
    if count:
        return OutputLayout("nms", num_names or 80, (bi, si, ci, count[0]), extra={"kind": "boxes_scores_classes"})
    return OutputLayout("nms", num_names or 80, (bi, si, ci), extra={"kind": "boxes_scores_classes"})


# ---------------------------------------------------------------------- decoders
_Result = tuple[np.ndarray, np.ndarray, np.ndarray]


def _empty() -> _Result:
    return np.zeros((0, 4), np.float32), np.zeros(0, np.float32), np.zeros(0, np.int64)


def _best_class(cls_scores: np.ndarray, obj: np.ndarray | None, conf: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rows kept, their score and best class: score = obj * max class score (obj optional)."""
    cid = np.argmax(cls_scores, axis=1)
    best = np.take_along_axis(cls_scores, cid[:, None], axis=1)[:, 0]
    score = best * obj if obj is not None else best
    keep = np.flatnonzero(score > conf)
    return keep, score[keep].astype(np.float32), cid[keep].astype(np.int64)


def _xywh_to_xyxy(cx, cy, w, h) -> np.ndarray:
    return np.stack([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2], axis=1).astype(np.float32)


def _yolox(layout: OutputLayout, outs: list[np.ndarray], input_hw, conf: float) -> _Result:
    p = outs[0].reshape(-1, 5 + layout.num_classes).astype(np.float32, copy=False)
    H, W = input_hw
    keep, score, cid = _best_class(p[:, 5:], p[:, 4], conf)
    if not keep.size:
        return _empty()
    grids, strides = [], []
    for s in layout.strides:
        gy, gx = np.mgrid[0:math.ceil(H / s), 0:math.ceil(W / s)]  # as grid_count counts them
        grids.append(np.stack([gx.ravel(), gy.ravel()], axis=1))
        strides.append(np.full(gx.size, s))
    grid = np.concatenate(grids)[keep].astype(np.float64)
    stride = np.concatenate(strides)[keep].astype(np.float64)
    r = p[keep].astype(np.float64)
    cx = (r[:, 0] + grid[:, 0]) * stride
    cy = (r[:, 1] + grid[:, 1]) * stride
    w = np.exp(r[:, 2]) * stride
    h = np.exp(r[:, 3]) * stride
    return _xywh_to_xyxy(cx, cy, w, h), score, cid


def _yolov5(layout: OutputLayout, outs, input_hw, conf) -> _Result:
    p = outs[0].reshape(-1, 5 + layout.num_classes)
    keep, score, cid = _best_class(p[:, 5:], p[:, 4], conf)
    r = p[keep].astype(np.float64)
    return _xywh_to_xyxy(r[:, 0], r[:, 1], r[:, 2], r[:, 3]), score, cid


def _yolov8(layout: OutputLayout, outs, input_hw, conf) -> _Result:
    p = outs[0].reshape(4 + layout.num_classes, -1) if layout.extra.get("transposed", True) \
        else outs[0].reshape(-1, 4 + layout.num_classes).T
    cls = p[4:]
    cid = np.argmax(cls, axis=0)
    best = np.take_along_axis(cls, cid[None, :], axis=0)[0]
    keep = np.flatnonzero(best > conf)
    r = p[:4, keep].astype(np.float64)
    return _xywh_to_xyxy(r[0], r[1], r[2], r[3]), best[keep].astype(np.float32), cid[keep].astype(np.int64)


def _softmax_integral(dist: np.ndarray, reg_max: int) -> np.ndarray:
    """(K, 4 * (R + 1)) logits -> (K, 4) expected distance in stride units (GFL integral)."""
    d = dist.reshape(-1, 4, reg_max + 1).astype(np.float64)
    d = np.exp(d - d.max(axis=2, keepdims=True))
    d /= d.sum(axis=2, keepdims=True)
    return d @ np.arange(reg_max + 1, dtype=np.float64)


def _distance_boxes(cx, cy, dist, stride) -> np.ndarray:
    return np.stack([cx - dist[:, 0] * stride, cy - dist[:, 1] * stride,
                     cx + dist[:, 2] * stride, cy + dist[:, 3] * stride], axis=1).astype(np.float32)


def _nanodet(layout: OutputLayout, outs, input_hw, conf) -> _Result:
    H, W = input_hw
    boxes, scores, ids = [], [], []
    for level, s in enumerate(layout.strides):
        cls = outs[2 * level].reshape(-1, layout.num_classes)
        dis = outs[2 * level + 1].reshape(cls.shape[0], -1)
        keep, score, cid = _best_class(cls, None, conf)
        if not keep.size:
            continue
        fw = math.ceil(W / s)
        cx = (keep % fw + 0.5) * s  # NanoDet (v0.x GFL head): centre of the cell
        cy = (keep // fw + 0.5) * s
        boxes.append(_distance_boxes(cx, cy, _softmax_integral(dis[keep], layout.reg_max), s))
        scores.append(score)
        ids.append(cid)
    if not boxes:
        return _empty()
    return np.concatenate(boxes), np.concatenate(scores), np.concatenate(ids)


def _nanodet_plus(layout: OutputLayout, outs, input_hw, conf) -> _Result:
    H, W = input_hw
    c = layout.num_classes
    p = outs[0].reshape(-1, c + 4 * (layout.reg_max + 1))
    keep, score, cid = _best_class(p[:, :c], None, conf)
    if not keep.size:
        return _empty()
    cxs, cys, ss = [], [], []
    for s in layout.strides:
        fh, fw = math.ceil(H / s), math.ceil(W / s)
        gy, gx = np.mgrid[0:fh, 0:fw]
        cxs.append(gx.ravel() * s)  # NanoDet-Plus: centre priors at the cell corner (x * stride)
        cys.append(gy.ravel() * s)
        ss.append(np.full(fh * fw, s))
    cx, cy, st = (np.concatenate(v)[keep].astype(np.float64) for v in (cxs, cys, ss))
    dist = _softmax_integral(p[keep, c:], layout.reg_max)
    return _distance_boxes(cx, cy, dist, st), score, cid


def _fastestdet(layout: OutputLayout, outs, input_hw, conf) -> _Result:
    H, W = input_hw
    p = outs[0][0]  # (5 + C, gh, gw)
    gh, gw = p.shape[1:]
    p = p.reshape(p.shape[0], -1)
    obj = p[0].astype(np.float64)
    cls = p[5:]
    cid = np.argmax(cls, axis=0)
    best = np.take_along_axis(cls, cid[None, :], axis=0)[0].astype(np.float64)
    score = np.power(np.clip(obj, 0, 1), 0.6) * np.power(np.clip(best, 0, 1), 0.4)
    keep = np.flatnonzero(score > conf)
    if not keep.size:
        return _empty()
    gx, gy = keep % gw, keep // gw
    cx = (gx + np.tanh(p[1, keep].astype(np.float64))) / gw * W
    cy = (gy + np.tanh(p[2, keep].astype(np.float64))) / gh * H
    w = 1.0 / (1.0 + np.exp(-p[3, keep].astype(np.float64))) * W
    h = 1.0 / (1.0 + np.exp(-p[4, keep].astype(np.float64))) * H
    return _xywh_to_xyxy(cx, cy, w, h), score[keep].astype(np.float32), cid[keep].astype(np.int64)


def _nms_included(layout: OutputLayout, outs, input_hw, conf) -> _Result:
    kind = layout.extra.get("kind")
    if kind == "xyxy_score_class":
        p = outs[0].reshape(-1, 6)
        boxes, scores, cls = p[:, :4], p[:, 4], p[:, 5]
    elif kind == "batch_xyxy_class_score":
        p = outs[0].reshape(-1, 7)
        boxes, cls, scores = p[:, 1:5], p[:, 5], p[:, 6]
    elif kind == "dets_labels":
        p = outs[0].reshape(-1, 5)
        boxes, scores, cls = p[:, :4], p[:, 4], outs[1].reshape(-1)
    else:
        boxes = outs[0].reshape(-1, 4)
        scores = outs[1].reshape(-1)
        cls = outs[2].reshape(-1)
        if len(outs) > 3:  # num_dets: only the first rows are real
            n = int(np.asarray(outs[3]).reshape(-1)[0])
            boxes, scores, cls = boxes[:n], scores[:n], cls[:n]
    keep = np.flatnonzero((scores > conf) & np.isfinite(cls) & (cls >= 0) & (cls < 2**31))
    b = boxes[keep].astype(np.float32)
    b = np.stack([np.minimum(b[:, 0], b[:, 2]), np.minimum(b[:, 1], b[:, 3]),
                  np.maximum(b[:, 0], b[:, 2]), np.maximum(b[:, 1], b[:, 3])], axis=1) if b.size else b.reshape(0, 4)
    return b, scores[keep].astype(np.float32), np.rint(cls[keep]).astype(np.int64)


_DECODERS = {"yolox": _yolox, "yolov5": _yolov5, "yolov8": _yolov8, "nanodet": _nanodet,
             "nanodet_plus": _nanodet_plus, "fastestdet": _fastestdet, "nms": _nms_included}


def decode(layout: OutputLayout, outputs: Sequence[np.ndarray], input_hw: tuple[int, int], conf_threshold: float) -> _Result:
    """Decode raw outputs (all session outputs, in session order) with ``layout``'s decoder."""
    outs = [np.asarray(outputs[i]) for i in layout.outputs]
    with np.errstate(all="ignore"):  # hostile values become NaN/inf here and are dropped by the caller
        return _DECODERS[layout.family](layout, outs, input_hw, float(conf_threshold))
