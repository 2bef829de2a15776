"""OnnxDetector on outputs that used to crash or mislead (issue #15 item 11): inverted boxes (x1 > x2 from an
export without DFL, e.g. YOLO26) are dropped and counted instead of making nms() raise inside detect();
dynamic-size exports use the metadata size, and ``minimal_padding`` letterboxes to multiples of 32 as
Ultralytics does; an inference failure is a ModelError naming the model."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from detectors import InputSizeError, ModelError, OnnxDetector, nms
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


def test_minimal_padding_needs_a_model_that_runs_at_other_sizes():
    # a fixed-size export gets its height and width freed; one whose outputs do not follow its input's size (here:
    # constants) cannot be letterboxed into a smaller rectangle
    raw = _yolov8_raw([(100, 100, 40, 40)], [0.9])
    with pytest.raises(InputSizeError, match=r"`minimal_padding`: model <model bytes> does not run at input sizes "
                                             r"other than 416x416 \(tried 416x224: the same outputs"):
        OnnxDetector(constant_detector({"output0": raw}), minimal_padding=True)
    assert OnnxDetector(constant_detector({"output0": raw})).input_size == (416, 416)  # the square: fine
    with pytest.raises(ValueError, match="`minimal_padding` must be True or False"):
        OnnxDetector(shape_echo_detector(metadata=META), minimal_padding="yes")


def test_scores_that_are_logits_are_a_model_error_from_detect():
    raw = _yolov8_raw([(100, 100, 40, 40)], [7.5])
    det = OnnxDetector(constant_detector({"output0": raw}))  # the blank dry run does not look at scores
    with pytest.raises(ModelError, match="expected probabilities"):
        det.detect(np.zeros((416, 416, 3), np.uint8))


def test_free_image_dims_rewrites_only_the_declared_shapes():
    """The wire-format rewrite read back by the onnx package: the input's height and width named free, the outputs'
    sizes unknown (rank kept), the inner tensors' recorded shapes gone, everything else (nodes, weights, metadata,
    opsets) equal."""
    import onnx
    from onnx import TensorProto, helper, numpy_helper

    from detectors.onnx_detector import _free_image_dims

    w = numpy_helper.from_array(np.ones((4, 3, 3, 3), np.float32), "w")
    nodes = [helper.make_node("Conv", ["images", "w"], ["f"], pads=[1, 1, 1, 1]),
             helper.make_node("Relu", ["f"], ["out"])]
    image = helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, 416, 416])
    graph = helper.make_graph(nodes, "g", [image],
                              [helper.make_tensor_value_info("out", TensorProto.FLOAT, [1, 4, 416, 416])],
                              initializer=[w],
                              value_info=[helper.make_tensor_value_info("f", TensorProto.FLOAT, [1, 4, 416, 416])])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    helper.set_model_props(model, {"imgsz": "[416, 416]"})
    freed = onnx.load_model_from_string(_free_image_dims(model.SerializeToString(), "images", (2, 3)))
    dims = freed.graph.input[0].type.tensor_type.shape.dim
    assert [d.dim_value for d in dims[:2]] == [1, 3] and [d.dim_param for d in dims[2:]] == ["height", "width"]
    out_dims = freed.graph.output[0].type.tensor_type.shape.dim
    assert len(out_dims) == 4 and not any(d.HasField("dim_value") or d.HasField("dim_param") for d in out_dims)
    assert len(freed.graph.value_info) == 0
    assert freed.graph.output[0].type.tensor_type.elem_type == TensorProto.FLOAT
    assert freed.graph.node == model.graph.node and freed.graph.initializer == model.graph.initializer
    assert freed.metadata_props == model.metadata_props and freed.opset_import == model.opset_import
    onnx.checker.check_model(freed)
    import onnxruntime as ort  # the freed model runs at another size

    out = ort.InferenceSession(freed.SerializeToString(), providers=["CPUExecutionProvider"]).run(
        None, {"images": np.ones((1, 3, 128, 416), np.float32)})[0]
    assert out.shape == (1, 4, 128, 416)


def test_free_image_dims_refuses_what_is_not_protobuf():
    from detectors.onnx_wire import pb_fields as _pb_fields

    with pytest.raises(ValueError, match="truncated protobuf"):
        _pb_fields(b"\x3a\x05ab")  # field 7, length 5, 2 bytes
    with pytest.raises(ValueError, match="wire type 3"):
        _pb_fields(b"\x0b")
