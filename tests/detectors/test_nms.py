"""Class-aware NMS against a plain reference, properties, errors."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from detectors import box_iou, nms


def _reference_nms(boxes, scores, classes, thr):
    """Slow, obvious greedy NMS: loops, per class."""
    order = sorted(range(len(scores)), key=lambda i: (-scores[i], i))
    keep = []
    for i in order:
        ok = True
        for k in keep:
            if classes[k] != classes[i]:
                continue
            x1, y1 = max(boxes[i][0], boxes[k][0]), max(boxes[i][1], boxes[k][1])
            x2, y2 = min(boxes[i][2], boxes[k][2]), min(boxes[i][3], boxes[k][3])
            inter = max(0.0, x2 - x1) * max(0.0, y2 - y1)
            a = (boxes[i][2] - boxes[i][0]) * (boxes[i][3] - boxes[i][1])
            b = (boxes[k][2] - boxes[k][0]) * (boxes[k][3] - boxes[k][1])
            union = a + b - inter
            if union > 0 and inter / union > thr:
                ok = False
                break
        if ok:
            keep.append(i)
    return keep


def test_known_example():
    boxes = np.array([[0, 0, 10, 10], [1, 1, 11, 11], [50, 50, 60, 60], [0, 0, 10, 10]], np.float32)
    scores = np.array([0.9, 0.8, 0.7, 0.95])
    classes = np.array([0, 0, 0, 1])
    # box 1 overlaps box 0 with IoU 81/119 = 0.68 -> suppressed; box 3 is another class -> kept
    np.testing.assert_array_equal(nms(boxes, scores, classes, iou_threshold=0.5), [3, 0, 2])
    np.testing.assert_array_equal(nms(boxes, scores, None, iou_threshold=0.5), [3, 2])  # class-agnostic
    np.testing.assert_array_equal(nms(boxes, scores, classes, iou_threshold=0.7), [3, 0, 1, 2])
    np.testing.assert_array_equal(nms(boxes, scores, classes, iou_threshold=0.5, max_detections=2), [3, 0])


def test_empty_and_dtype():
    keep = nms(np.zeros((0, 4)), np.zeros(0), np.zeros(0, int))
    assert keep.dtype == np.int64 and keep.shape == (0,)


def test_zero_area_boxes_do_not_divide_by_zero():
    boxes = np.array([[5, 5, 5, 5], [5, 5, 5, 5]], np.float32)
    np.testing.assert_array_equal(nms(boxes, np.array([0.5, 0.4]), iou_threshold=0.0), [0, 1])


def test_box_iou():
    iou = box_iou(np.array([[0, 0, 10, 10]]), np.array([[0, 0, 10, 10], [5, 0, 15, 10], [20, 20, 30, 30], [3, 3, 3, 3]]))
    np.testing.assert_allclose(iou, [[1.0, 50 / 150, 0.0, 0.0]])


@pytest.mark.parametrize(
    ("args", "kwargs", "match"),
    [
        ((np.zeros((2, 3)), np.zeros(2)), {}, r"`xyxy` must have shape \(N, 4\)"),
        ((np.zeros((2, 4)), np.zeros(3)), {}, r"`scores` must have shape \(2,\)"),
        ((np.array([[0, 0, np.nan, 1]]), np.ones(1)), {}, "must be finite"),
        ((np.array([[2, 0, 1, 1]]), np.ones(1)), {}, "x1 <= x2"),
        ((np.zeros((1, 4)), np.ones(1)), {"iou_threshold": 1.5}, r"`iou_threshold` must be a number in \[0, 1\]"),
        ((np.zeros((1, 4)), np.ones(1)), {"max_detections": -1}, "`max_detections`"),
        ((np.zeros((1, 4)), np.ones(1), np.array([0.5])), {}, "`class_id` must be an integer array"),
    ],
)
def test_errors(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        nms(*args, **kwargs)


@settings(max_examples=450, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    n=st.integers(0, 40),
    n_classes=st.integers(1, 4),
    thr=st.sampled_from([0.0, 0.3, 0.45, 0.7, 1.0]),
    int_scores=st.booleans(),
)
def test_property_matches_reference(seed, n, n_classes, thr, int_scores):
    rng = np.random.default_rng(seed)
    xy = rng.uniform(-50, 200, (n, 2))
    wh = rng.uniform(0, 80, (n, 2)) * (rng.random((n, 1)) > 0.05)  # a few zero-size boxes
    boxes = np.concatenate([xy, xy + wh], axis=1).astype(np.float32)
    scores = rng.integers(0, 3, n).astype(float) if int_scores else rng.random(n)  # ties when int_scores
    classes = rng.integers(0, n_classes, n)
    keep = nms(boxes, scores, classes, iou_threshold=thr)
    assert keep.tolist() == _reference_nms(boxes.astype(np.float64).tolist(), scores.tolist(), classes.tolist(), thr)
    # no two kept boxes of one class overlap above the threshold
    iou = box_iou(boxes[keep], boxes[keep])
    same = classes[keep][:, None] == classes[keep][None, :]
    np.fill_diagonal(same, False)
    assert not np.any(iou[same] > thr + 1e-12)
