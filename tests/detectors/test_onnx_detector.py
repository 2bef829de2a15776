"""OnnxDetector on outputs that used to crash or mislead (issue #15 item 11): inverted boxes (x1 > x2 from an
export without DFL, e.g. YOLO26) are dropped and counted instead of making nms() raise inside detect();
dynamic-size exports use the metadata size, and ``minimal_padding`` letterboxes to multiples of 32 as
Ultralytics does; an inference failure is a ModelError naming the model."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from detectors import ModelError, OnnxDetector, nms
from tests.helpers.onnx_detectors import constant_detector, shape_echo_detector


def _yolov8_raw(boxes_xywh, scores, n=500, num_classes=80):
    raw = np.zeros((1, 4 + num_classes, n), np.float32)
    for i, (box, score) in enumerate(zip(boxes_xywh, scores)):
        raw[0, :4, i] = box
        raw[0, 4, i] = score
    return raw


def test_inverted_boxes_are_dropped_and_counted_not_a_crash(caplog):
    # rows 1 and 2 have negative width / height (a YOLO26-style export predicting negative distances)
    raw = _yolov8_raw([(100, 100, 40, 40), (200, 200, -30, 20), (300, 300, 20, -10)], [0.9, 0.8, 0.7])
    det = OnnxDetector(constant_detector({"output0": raw}))
    with np.testing.assert_raises(ValueError):  # what detect() used to run into
        nms(np.array([[215.0, 190, 185, 210]]), np.array([0.8]))
    with caplog.at_level(logging.WARNING, logger="detectors"):
        dets = det.detect(np.zeros((416, 416, 3), np.uint8))
    assert len(dets) == 1
    np.testing.assert_array_equal(dets.xyxy, np.float32([[80, 80, 120, 120]]))
    assert det.last_dropped == {"inverted": 2, "non_finite": 0}
    assert "dropped 2 box(es) with x1 > x2" in caplog.text
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="detectors"):
        det.detect(np.zeros((416, 416, 3), np.uint8))
    assert "dropped" not in caplog.text  # warned once per detector, counted every time
    assert det.last_dropped["inverted"] == 2


def test_only_inverted_boxes_give_no_detections():
    raw = _yolov8_raw([(200, 200, -30, -20)] * 3, [0.9, 0.8, 0.7])
    det = OnnxDetector(constant_detector({"output0": raw}))
    assert len(det.detect(np.zeros((300, 500, 3), np.uint8))) == 0
    assert det.last_dropped["inverted"] == 3


def test_nms_included_export_with_swapped_corners_is_repaired():
    raw = np.zeros((1, 300, 6), np.float32)
    raw[0, 0] = (120, 130, 80, 90, 0.9, 2)  # x1 > x2 and y1 > y2: the corners, swapped
    det = OnnxDetector(constant_detector({"output0": raw}))
    dets = det.detect(np.zeros((416, 416, 3), np.uint8))
    np.testing.assert_array_equal(dets.xyxy, np.float32([[80, 90, 120, 130]]))


META = {"imgsz": "[640, 640]", "stride": "32", "author": "Ultralytics"}


def test_dynamic_export_uses_the_metadata_size_by_default():
    det = OnnxDetector(shape_echo_detector(metadata=META))
    assert det.input_size == (640, 640) and not det.minimal_padding
    assert det.input_size_for(1242, 375) == (640, 640)
    dets = det.detect(np.zeros((375, 1242, 3), np.uint8))
    # the echoed box is the centre half of the 640x640 input: 320x320 about (320, 320), mapped back
    nh = round(375 * 640 / 1242)  # 193 rows, centred
    pad = (640 - nh) // 2
    expected = np.array([[160, 160 - pad, 480, 480 - pad]]) / [640 / 1242, nh / 375, 640 / 1242, nh / 375]
    np.testing.assert_allclose(dets.xyxy, np.clip(expected, 0, [1242, 375, 1242, 375]).astype(np.float32), atol=0.01)


@pytest.mark.parametrize(("size", "expected"), [((1242, 375), (640, 224)), ((640, 480), (640, 480)),
                                                ((480, 640), (480, 640)), ((1000, 1000), (640, 640)),
                                                ((100, 20), (640, 128))])
def test_minimal_padding_letterboxes_to_multiples_of_32(size, expected):
    det = OnnxDetector(shape_echo_detector(metadata=META), minimal_padding=True)
    assert det.input_size_for(*size) == expected
    w, h = size
    dets = det.detect(np.zeros((h, w, 3), np.uint8))
    # the model saw an input of `expected`: its echoed box is the middle half of that input
    r = min(640 / w, 640 / h)
    nw, nh = round(w * r), round(h * r)
    px, py = (expected[0] - nw) // 2, (expected[1] - nh) // 2
    ew, eh = expected
    box = np.array([[ew / 4 - px, eh / 4 - py, 3 * ew / 4 - px, 3 * eh / 4 - py]]) / [nw / w, nh / h, nw / w, nh / h]
    np.testing.assert_allclose(dets.xyxy, np.clip(box, 0, [w, h, w, h]).astype(np.float32), atol=0.02)


def test_minimal_padding_needs_a_dynamic_model():
    raw = _yolov8_raw([(100, 100, 40, 40)], [0.9])
    with pytest.raises(ValueError, match="`minimal_padding` needs a model with dynamic input size"):
        OnnxDetector(constant_detector({"output0": raw}), minimal_padding=True)
    with pytest.raises(ValueError, match="`minimal_padding` must be True or False"):
        OnnxDetector(shape_echo_detector(metadata=META), minimal_padding="yes")


def test_scores_that_are_logits_are_a_model_error_from_detect():
    raw = _yolov8_raw([(100, 100, 40, 40)], [7.5])
    det = OnnxDetector(constant_detector({"output0": raw}))  # the blank dry run does not look at scores
    with pytest.raises(ModelError, match="expected probabilities"):
        det.detect(np.zeros((416, 416, 3), np.uint8))
