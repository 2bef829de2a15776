"""Decoders, letterboxing and layout recognition with tiny ONNX models that emit known raw tensors.

Each model is built here with onnx.helper: its outputs are Constant nodes (independent of the input),
holding the raw tensor a real export of that family would give for boxes we chose. The detector must
give those boxes back in original-image pixels, through the letterbox of a non-square image.
"""

from __future__ import annotations

import math

import numpy as np
import onnx
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from onnx import TensorProto, helper, numpy_helper

from detectors import COCO_CLASSES, ModelError, ModelNotFoundError, OnnxDetector, Preprocessing
from detectors.decoders import grid_count


def onnx_model(outputs: dict[str, np.ndarray], *, input_shape=(1, 3, 416, 416), input_name="images",
               input_type=TensorProto.FLOAT, metadata: dict[str, str] | None = None, n_inputs: int = 1) -> bytes:
    """Serialized ONNX model: one image input (unused), outputs = the given constants."""
    nodes, outs = [], []
    for name, arr in outputs.items():
        nodes.append(helper.make_node("Constant", [], [name], value=numpy_helper.from_array(arr, f"{name}_value")))
        outs.append(helper.make_tensor_value_info(name, helper.np_dtype_to_tensor_dtype(arr.dtype), list(arr.shape)))
    inputs = [helper.make_tensor_value_info(input_name if i == 0 else f"extra{i}", input_type, list(input_shape))
              for i in range(n_inputs)]
    graph = helper.make_graph(nodes, "tiny", inputs, outs)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    if metadata:
        helper.set_model_props(model, metadata)
    onnx.checker.check_model(model)
    return model.SerializeToString()


def _image(width: int, height: int, grey: bool = False) -> np.ndarray:
    rng = np.random.default_rng(0)
    shape = (height, width) if grey else (height, width, 3)
    return rng.integers(0, 256, shape, dtype=np.uint8)


def _centre_to_orig(xyxy_in, pad_y, scale):
    b = np.asarray(xyxy_in, np.float64).copy()
    b[:, 1::2] -= pad_y
    return (b * scale).astype(np.float32)


def _sorted(dets):
    order = np.argsort(-dets.confidence, kind="stable")
    return dets[order]


# ------------------------------------------------------------------------------ YOLOX
def _yolox_raw(cells, width=416, height=416, num_classes=80):
    """cells: (stride, gx, gy, dx, dy, log_w, log_h, obj, cls, cls_score) -> ((1, N, 5+C) raw, expected xyxy input px)."""
    strides = (8, 16, 32)
    offsets = np.cumsum([0] + [math.ceil(height / s) * math.ceil(width / s) for s in strides])
    raw = np.zeros((1, offsets[-1], 5 + num_classes), np.float32)
    expected = []
    for s, gx, gy, dx, dy, lw, lh, obj, cls, sc in cells:
        row = offsets[strides.index(s)] + gy * math.ceil(width / s) + gx
        raw[0, row, :5] = (dx, dy, lw, lh, obj)
        raw[0, row, 5 + cls] = sc
        cx, cy = (gx + dx) * s, (gy + dy) * s
        w, h = math.exp(np.float32(lw)) * s, math.exp(np.float32(lh)) * s
        expected.append([cx - w / 2, cy - h / 2, cx + w / 2, cy + h / 2])
    return raw, np.asarray(expected)


class TestYolox:
    CELLS = [
        (8, 10, 20, 0.5, 0.25, 0.0, 0.0, 0.8, 2, 1.0),      # car, 8x8 px in the input
        (16, 3, 7, -0.25, 0.75, 0.0, 0.0, 0.5, 0, 0.9),     # person, score 0.45
        (32, 6, 5, 0.5, 0.5, 1.3, 0.7, 0.95, 3, 1.0),       # motorcycle, exp() sizes
        (32, 1, 1, 0.0, 0.0, 0.0, 0.0, 0.5, 5, 0.5),        # score 0.25: under the threshold
    ]

    def test_exact_boxes_through_top_left_letterbox(self):
        raw, expected_in = _yolox_raw(self.CELLS)
        det = OnnxDetector(onnx_model({"output": raw}), conf_threshold=0.3)
        assert det.family == "yolox" and det.input_size == (416, 416)
        dets = _sorted(det.detect(_image(832, 624)))  # r = 0.5, image top-left, no offset
        assert dets.labels == ["motorcycle", "car", "person"]
        np.testing.assert_array_equal(dets.confidence, np.float32([0.95, 0.8, 0.45]))
        exp = (expected_in * 2.0).astype(np.float32)
        np.testing.assert_array_equal(dets.xyxy[1:], exp[[0, 1]])  # exp(0) = 1: exact
        np.testing.assert_allclose(dets.xyxy[0], exp[2], atol=1e-3)

    def test_non_square_model_input(self):
        cells = [(16, 12, 9, 0.5, 0.5, 0.0, 0.0, 1.0, 7, 0.75)]  # truck
        raw, expected_in = _yolox_raw(cells, width=320, height=256)
        assert raw.shape == (1, 1680, 85) == (1, grid_count(256, 320, (8, 16, 32)), 85)
        det = OnnxDetector(onnx_model({"output": raw}, input_shape=(1, 3, 256, 320)))
        assert det.family == "yolox" and det.input_size == (320, 256)
        dets = det.detect(_image(640, 640))  # r = 0.4 -> 256 x 256 at the top-left, back: x 2.5
        np.testing.assert_array_equal(dets.xyxy, (expected_in * 2.5).astype(np.float32))
        assert dets.labels == ["truck"]

    def test_input_size_not_a_multiple_of_32(self):
        # 336 x 264: stride-32 maps are ceil(336/32) x ceil(264/32) = 11 x 9, as a strided conv gives them;
        # the last column/row of every stride must decode at its own place
        cells = [(32, 10, 8, 0.25, 0.0, math.log(0.25), math.log(0.25), 1.0, 7, 0.75), (8, 41, 32, 0.5, 0.5, 0.0, 0.0, 1.0, 2, 0.9),
                 (16, 0, 0, 0.5, 0.5, 0.0, 0.0, 1.0, 0, 0.8)]
        raw, expected_in = _yolox_raw(cells, width=336, height=264)
        assert raw.shape == (1, grid_count(264, 336, (8, 16, 32)), 85) == (1, 42 * 33 + 21 * 17 + 11 * 9, 85)
        det = OnnxDetector(onnx_model({"output": raw}, input_shape=(1, 3, 264, 336)))
        assert det.family == "yolox" and det.input_size == (336, 264)
        dets = _sorted(det.detect(_image(336, 264)))  # r = 1: input pixels
        assert dets.labels == ["car", "person", "truck"]
        np.testing.assert_allclose(dets.xyxy, expected_in[[1, 2, 0]].astype(np.float32), atol=1e-4)
        with pytest.raises(ValueError, match="YOLOX raw output needs N = 1842 grid cells"):
            OnnxDetector(onnx_model({"output": raw[:, :-1]}, input_shape=(1, 3, 264, 336)), family="yolox")

    def test_preprocessing_bgr_0_255_top_left_pad_114(self):
        raw, _ = _yolox_raw(self.CELLS)
        det = OnnxDetector(onnx_model({"output": raw}))
        img = np.empty((312, 416, 3), np.uint8)
        img[:] = (10, 20, 30)
        x, lb = det.preprocess(np.tile(img, (2, 2, 1)))  # 832 x 624
        assert x.shape == (1, 3, 416, 416) and x.dtype == np.float32
        assert (lb.pad_x, lb.pad_y, lb.new_width, lb.new_height) == (0, 0, 416, 312)
        np.testing.assert_array_equal(x[0, :, :312, :].reshape(3, -1).max(1), [10, 20, 30])
        np.testing.assert_array_equal(x[0, :, :312, :].reshape(3, -1).min(1), [10, 20, 30])
        assert np.all(x[0, :, 312:, :] == 114)


# ------------------------------------------------------------------------------ YOLOv5 / YOLOv8
BOXES_IN = np.array([[100, 60, 180, 140], [0, 52, 416, 364], [300.5, 200.25, 310.75, 220]], np.float64)
CLASSES = [2, 0, 79]
SCORES = [0.9, 0.6, 0.35]


def _xywh(b):
    return np.stack([(b[:, 0] + b[:, 2]) / 2, (b[:, 1] + b[:, 3]) / 2, b[:, 2] - b[:, 0], b[:, 3] - b[:, 1]], 1)


class TestUltralytics:
    def _check(self, det, image=(832, 624)):
        dets = _sorted(det.detect(_image(*image)))
        assert dets.labels == [COCO_CLASSES[c] for c in CLASSES]
        np.testing.assert_array_equal(dets.confidence, np.float32(SCORES))
        # centred: 624 x 0.5 = 312 rows at 52..364; back: (y - 52) x 2, x x 2
        np.testing.assert_array_equal(dets.xyxy, _centre_to_orig(BOXES_IN, 52, 2.0))
        return dets

    def test_yolov5_decoded_xywh_with_objectness(self):
        n = 3 * grid_count(416, 416, (8, 16, 32))
        raw = np.zeros((1, n, 85), np.float32)
        rows = [5, 9000, 10646]
        raw[0, rows, :4] = _xywh(BOXES_IN)
        raw[0, rows, 4] = SCORES
        raw[0, rows, 5 + np.array(CLASSES)] = 1.0
        raw[0, 100, :5] = (50, 50, 10, 10, 0.2)  # objectness 0.2: dropped
        raw[0, 100, 5] = 1.0
        det = OnnxDetector(onnx_model({"output": raw}))
        assert det.family == "yolov5"
        self._check(det)

    def test_yolov8_transposed_no_objectness(self):
        raw = np.zeros((1, 84, 500), np.float32)
        cols = [0, 250, 499]
        raw[0, :4, cols] = _xywh(BOXES_IN)
        raw[0, 4 + np.array(CLASSES), cols] = SCORES
        raw[0, 4 + 3, 7] = 0.29  # under 0.3
        det = OnnxDetector(onnx_model({"output0": raw}))
        assert det.family == "yolov8"
        self._check(det)

    def test_yolov8_metadata_names_dynamic_input(self):
        raw = np.zeros((1, 7, 300), np.float32)
        raw[0, :4, 0] = (320, 320, 64, 32)
        raw[0, 4 + 2, 0] = 0.75
        meta = {"names": "{0: 'cone', 1: 'buoy', 2: 'dock'}", "imgsz": "[640, 640]", "stride": "32",
                "author": "Ultralytics"}
        det = OnnxDetector(onnx_model({"output0": raw}, input_shape=("batch", 3, "height", "width"), metadata=meta))
        assert det.class_names == ("cone", "buoy", "dock") and det.input_size == (640, 640)
        dets = det.detect(_image(1280, 640))  # r = 0.5, 320 rows at 160..480
        assert dets.labels == ["dock"]
        np.testing.assert_array_equal(dets.xyxy, np.float32([[576, 288, 704, 352]]))
        with pytest.raises(ValueError, match="multiples of 32"):
            OnnxDetector(onnx_model({"output0": raw}, input_shape=("batch", 3, "height", "width")), input_size=100)
        small = OnnxDetector(onnx_model({"output0": raw}, input_shape=(1, 3, "h", "w"), metadata=meta), input_size=(320, 256))
        assert small.input_size == (320, 256)

    def test_preprocessing_rgb_scaled_centred(self):
        raw = np.zeros((1, 84, 500), np.float32)
        det = OnnxDetector(onnx_model({"output0": raw}))
        img = np.empty((624, 832, 3), np.uint8)
        img[:] = (10, 20, 30)
        x, lb = det.preprocess(img)
        assert (lb.pad_x, lb.pad_y) == (0, 52)
        np.testing.assert_allclose(x[0, :, 52:364, :].reshape(3, -1).mean(1), np.float32([30, 20, 10]) / 255, rtol=1e-6)
        np.testing.assert_allclose(x[0, :, :52, :], 114 / 255, rtol=1e-6)
        np.testing.assert_allclose(x[0, :, 364:, :], 114 / 255, rtol=1e-6)

    def test_nhwc_input(self):
        raw = np.zeros((1, 84, 500), np.float32)
        raw[0, :4, 0] = (208, 208, 100, 100)
        raw[0, 4, 0] = 0.5
        det = OnnxDetector(onnx_model({"output0": raw}, input_shape=(1, 416, 416, 3)))
        assert not det.nchw
        x, _ = det.preprocess(_image(416, 416))
        assert x.shape == (1, 416, 416, 3)
        np.testing.assert_array_equal(det.detect(_image(416, 416)).xyxy, np.float32([[158, 158, 258, 258]]))


# ------------------------------------------------------------------------------ NanoDet
def _nanodet_outputs(cells, width=320, height=320, reg_max=7, num_classes=80):
    outs = {}
    expected = []
    dis_levels = {}
    for s in (8, 16, 32):
        n = math.ceil(height / s) * math.ceil(width / s)
        outs[f"cls_pred_stride_{s}"] = np.zeros((1, n, num_classes), np.float32)
        dis_levels[s] = np.full((1, n, 4 * (reg_max + 1)), -1e4, np.float32)
    for s, gx, gy, bins, cls, score in cells:
        fw = math.ceil(width / s)
        idx = gy * fw + gx
        outs[f"cls_pred_stride_{s}"][0, idx, cls] = score
        dist = []
        for side, b in enumerate(bins):  # an int bin (one-hot) or a pair of bins with equal weight
            chosen = [b] if isinstance(b, int) else list(b)
            dis_levels[s][0, idx, side * (reg_max + 1) + np.array(chosen)] = 0.0
            dist.append(np.mean(chosen) * s)
        cx, cy = (gx + 0.5) * s, (gy + 0.5) * s
        expected.append([cx - dist[0], cy - dist[1], cx + dist[2], cy + dist[3]])
    for s in (8, 16, 32):
        outs[f"dis_pred_stride_{s}"] = dis_levels[s]
    return outs, np.asarray(expected)


class TestNanodet:
    CELLS = [(16, 5, 7, (2, 3, 4, 1), 0, 0.7), (8, 20, 17, ((2, 3), 1, 0, (5, 6)), 56, 0.5), (32, 9, 9, (1, 1, 0, 0), 2, 0.2)]

    def test_exact_gfl_integral_through_centred_letterbox(self):
        outs, expected_in = _nanodet_outputs(self.CELLS)
        det = OnnxDetector(onnx_model(outs, input_shape=(1, 3, 320, 320), input_name="input.1"))
        assert det.family == "nanodet" and det.layout.strides == (8, 16, 32) and det.layout.reg_max == 7
        dets = _sorted(det.detect(_image(640, 480)))  # r = 0.5, 240 rows at 40..280
        assert dets.labels == ["person", "chair"]
        np.testing.assert_array_equal(dets.confidence, np.float32([0.7, 0.5]))
        np.testing.assert_array_equal(dets.xyxy, _centre_to_orig(expected_in[:2], 40, 2.0))

    def test_output_order_does_not_matter(self):
        outs, expected_in = _nanodet_outputs(self.CELLS[:1])
        shuffled = {k: outs[k] for k in sorted(outs, key=lambda k: (k[-2:], k))}  # interleaved by stride
        det = OnnxDetector(onnx_model(shuffled, input_shape=(1, 3, 320, 320)))
        assert det.family == "nanodet"
        np.testing.assert_array_equal(det.detect(_image(640, 480)).xyxy, _centre_to_orig(expected_in, 40, 2.0))

    def test_preprocessing_mean_std_bgr(self):
        outs, _ = _nanodet_outputs(self.CELLS)
        det = OnnxDetector(onnx_model(outs, input_shape=(1, 3, 320, 320)))
        img = np.empty((480, 640, 3), np.uint8)
        img[:] = (10, 20, 30)
        x, _ = det.preprocess(img)
        mean, std = np.float32([103.53, 116.28, 123.675]), np.float32([57.375, 57.12, 58.395])
        np.testing.assert_allclose(x[0, :, 100, 100], (np.float32([10, 20, 30]) - mean) / std, rtol=1e-5)
        np.testing.assert_allclose(x[0, :, 0, 0], -mean / std, rtol=1e-5)  # black border


# ------------------------------------------------------------------------------ NMS included, FastestDet
class TestNmsIncluded:
    def test_boxes_scores_classes_num_dets(self):
        k = 100
        boxes = np.zeros((1, k, 4), np.float32)
        boxes[0, :3] = BOXES_IN
        scores = np.zeros((1, k), np.float32)
        scores[0, :3] = SCORES
        scores[0, 3:] = 0.99  # beyond num_dets: padding that must be ignored
        classes = np.zeros((1, k), np.int64)
        classes[0, :3] = CLASSES
        outs = {"num_dets": np.array([[3]], np.int64), "det_boxes": boxes, "det_scores": scores, "det_classes": classes}
        det = OnnxDetector(onnx_model(outs))
        assert det.family == "nms"
        dets = det.detect(_image(832, 624))
        assert dets.labels == [COCO_CLASSES[c] for c in CLASSES]
        np.testing.assert_array_equal(dets.xyxy, _centre_to_orig(BOXES_IN, 52, 2.0))

    def test_end2end_single_output(self):
        raw = np.zeros((1, 300, 6), np.float32)
        raw[0, :3, :4] = BOXES_IN
        raw[0, :3, 4] = SCORES
        raw[0, :3, 5] = CLASSES
        raw[0, 3, :] = (1, 1, 2, 2, 0.1, 4)  # under the threshold
        det = OnnxDetector(onnx_model({"output0": raw}))
        assert det.family == "nms"
        dets = det.detect(_image(832, 624))
        np.testing.assert_array_equal(dets.xyxy, _centre_to_orig(BOXES_IN, 52, 2.0))
        np.testing.assert_array_equal(dets.confidence, np.float32(SCORES))


def test_fastestdet_grid_stretched_input():
    raw = np.zeros((1, 85, 22, 22), np.float32)
    raw[0, 0, 10, 10] = 1.0            # objectness
    raw[0, 5 + 16, 10, 10] = 1.0       # dog, softmax score 1
    raw[0, 1:5, 10, 10] = 0.0          # tanh(0) = 0 offsets, sigmoid(0) = 0.5 of the input size
    det = OnnxDetector(onnx_model({"758": raw}, input_shape=(1, 3, 352, 352)))
    assert det.family == "fastestdet" and det.preprocessing.keep_ratio is False
    dets = det.detect(_image(704, 528))  # stretched: x 2, y 1.5
    assert dets.labels == ["dog"] and dets.confidence.tolist() == [1.0]
    np.testing.assert_array_equal(dets.xyxy, np.float32([[144, 108, 496, 372]]))


# ------------------------------------------------------------------------------ family choice
class TestFamilyChoice:
    def test_yolox_vs_yolov5_by_anchor_count(self):
        assert OnnxDetector(onnx_model({"o": np.zeros((1, 3549, 85), np.float32)})).family == "yolox"
        assert OnnxDetector(onnx_model({"o": np.zeros((1, 10647, 85), np.float32)})).family == "yolov5"
        # 640 input: 8400 anchor points vs 25200 anchors
        assert OnnxDetector(onnx_model({"o": np.zeros((1, 8400, 85), np.float32)}, input_shape=(1, 3, 640, 640))).family == "yolox"
        assert OnnxDetector(onnx_model({"o": np.zeros((1, 25200, 85), np.float32)}, input_shape=(1, 3, 640, 640))).family == "yolov5"

    def test_ultralytics_metadata_means_yolov5(self):
        names = str(dict(enumerate(COCO_CLASSES)))
        det = OnnxDetector(onnx_model({"o": np.zeros((1, 3549, 85), np.float32)}, metadata={"stride": "32", "names": names}))
        assert det.family == "yolov5" and det.class_names == COCO_CLASSES

    def test_explicit_family_override(self):
        det = OnnxDetector(onnx_model({"o": np.zeros((1, 3549, 85), np.float32)}), family="yolov5")
        assert det.family == "yolov5" and det.preprocessing.rgb
        with pytest.raises(ValueError, match="`family` must be one of"):
            OnnxDetector(onnx_model({"o": np.zeros((1, 3549, 85), np.float32)}), family="yolov99")
        with pytest.raises(ModelError, match="YOLOX raw output needs N = 3549"):
            OnnxDetector(onnx_model({"o": np.zeros((1, 10647, 85), np.float32)}), family="yolox")

    def test_file_name_decides_when_the_count_does_not(self, tmp_path):
        data = onnx_model({"o": np.zeros((1, 5000, 85), np.float32)})
        with pytest.raises(ModelError, match=r"neither the YOLOX count 3549 nor the YOLOv5 count 10647.*\(1, 5000, 85\)"):
            OnnxDetector(data)
        (tmp_path / "my_yolov5_custom.onnx").write_bytes(data)
        assert OnnxDetector(tmp_path / "my_yolov5_custom.onnx").family == "yolov5"

    @pytest.mark.parametrize(
        "outputs",
        [
            {"o": np.zeros((1, 10), np.float32)},
            {"o": np.zeros((1, 3549, 4), np.float32)},
            {"o": np.zeros((2, 3, 4, 5, 6), np.float32)},
            {"a": np.zeros((1, 100, 4), np.float32), "b": np.zeros((1, 7), np.float32)},
        ],
    )
    def test_unknown_layout_names_the_shapes(self, outputs):
        with pytest.raises(ModelError, match="unrecognised detector output layout") as info:
            OnnxDetector(onnx_model(outputs))
        for name, arr in outputs.items():
            assert f"{name} {tuple(arr.shape)}" in str(info.value)

    def test_class_count_needs_names(self, tmp_path):
        raw = np.zeros((1, 3549, 8), np.float32)  # YOLOX with 3 classes, no names stored
        with pytest.raises(ModelError, match="stores no class names and is not COCO-80; pass names="):
            OnnxDetector(onnx_model({"o": raw}))
        assert OnnxDetector(onnx_model({"o": raw}), names=["a", "b", "c"]).class_names == ("a", "b", "c")
        f = tmp_path / "names.txt"
        f.write_text("a\nb\n\nc\n")
        assert OnnxDetector(onnx_model({"o": raw}), names=f).class_names == ("a", "b", "c")
        with pytest.raises(ModelError, match="`names` list 2 classes but model .* outputs 3"):
            OnnxDetector(onnx_model({"o": raw}), names=["a", "b"])
        with pytest.raises(FileNotFoundError, match="names file"):
            OnnxDetector(onnx_model({"o": raw}), names=tmp_path / "missing.txt")


# ------------------------------------------------------------------------------ options and bad input
def _yolox_model():
    raw, _ = _yolox_raw(TestYolox.CELLS)
    return onnx_model({"output": raw})


class TestOptionsAndErrors:
    def test_classes_filter(self):
        model = _yolox_model()
        assert OnnxDetector(model, classes=["car", "person"]).detect(_image(832, 624)).labels in (["car", "person"], ["person", "car"])
        assert OnnxDetector(model, classes=[3]).detect(_image(832, 624)).labels == ["motorcycle"]
        with pytest.raises(ValueError, match=r"`classes`: unknown class name 'cars'; valid names: person"):
            OnnxDetector(model, classes=["cars"])
        with pytest.raises(ValueError, match="`classes` entries"):
            OnnxDetector(model, classes=[80])

    @pytest.mark.parametrize(
        ("kwargs", "match"),
        [
            ({"conf_threshold": 1.5}, r"`conf_threshold` must be a number in \[0, 1\]"),
            ({"conf_threshold": float("nan")}, "`conf_threshold`"),
            ({"iou_threshold": -0.1}, "`iou_threshold`"),
            ({"threads": 0}, "`threads` must be a positive int"),
            ({"threads": 1.5}, "`threads`"),
            ({"providers": ("NoSuchProvider",)}, r"`providers`: 'NoSuchProvider' is not available"),
            ({"max_detections": 0}, "`max_detections`"),
            ({"input_size": 320}, r"`input_size` \(320, 320\) does not match the model's fixed input size \(416, 416\)"),
            ({"preprocessing": "bgr"}, "`preprocessing` must be a detectors.Preprocessing"),
        ],
    )
    def test_bad_options(self, kwargs, match):
        with pytest.raises(ValueError, match=match):
            OnnxDetector(_yolox_model(), **kwargs)

    @pytest.mark.parametrize(
        ("image", "match"),
        [
            (np.zeros((100, 100, 3), np.float32), "must have dtype uint8.*got float32"),
            (np.zeros((100, 100, 3), np.uint16), "must have dtype uint8.*got uint16"),
            (np.zeros((100, 100, 2), np.uint8), r"must have shape \(H, W\), \(H, W, 1\), \(H, W, 3\) or \(H, W, 4\), got \(100, 100, 2\)"),
            (np.zeros((2, 100, 100, 3), np.uint8), "must have shape"),
            (np.zeros((0, 100, 3), np.uint8), "is empty"),
            ([[0, 1], [2, 3]], "must be a numpy array"),
        ],
    )
    def test_bad_images(self, image, match):
        det = OnnxDetector(_yolox_model())
        with pytest.raises(ValueError, match=r"`image` " + match):
            det.detect(image)

    def test_grey_and_bgra_accepted(self):
        det = OnnxDetector(_yolox_model())
        ref = det.detect(_image(832, 624))
        for img in (_image(832, 624, grey=True), _image(832, 624, grey=True)[:, :, None], np.dstack([_image(832, 624)] + [_image(832, 624, True)])):
            got = det.detect(img)
            np.testing.assert_array_equal(got.xyxy, ref.xyxy)

    def test_views_with_odd_strides(self):
        det = OnnxDetector(_yolox_model())
        img = _image(832, 624)
        flipped = det.detect(img[:, ::-1])
        np.testing.assert_array_equal(flipped.xyxy, det.detect(np.ascontiguousarray(img[:, ::-1])).xyxy)
        assert len(det.detect(img[::2, ::2, :])) == 3

    def test_timings_recorded(self):
        det = OnnxDetector(_yolox_model())
        det.detect(_image(100, 50))
        assert set(det.last_timings_ms) == {"preprocess", "inference", "postprocess", "total"}
        assert all(v >= 0 for v in det.last_timings_ms.values())

    def test_missing_file(self, tmp_path):
        with pytest.raises(ModelNotFoundError, match="does not exist"):
            OnnxDetector(tmp_path / "nope.onnx")
        with pytest.raises(FileNotFoundError):
            OnnxDetector(str(tmp_path / "nope.onnx"))

    @pytest.mark.parametrize("content", [b"", b"not an onnx model at all\n", bytes(range(256)) * 40])
    def test_corrupt_file(self, tmp_path, content):
        path = tmp_path / "broken.onnx"
        path.write_bytes(content)
        with pytest.raises(ModelError, match=r"cannot load ONNX model .*broken.onnx"):
            OnnxDetector(path)

    def test_truncated_real_model(self, tmp_path, yolox_nano):
        path = tmp_path / "yolox_nano.onnx"
        path.write_bytes(yolox_nano.read_bytes()[:200_000])
        with pytest.raises(ModelError, match="cannot load ONNX model"):
            OnnxDetector(path)

    def test_bad_inputs_of_the_model(self):
        raw = np.zeros((1, 3549, 85), np.float32)
        with pytest.raises(ModelError, match="must have one image input, has 2"):
            OnnxDetector(onnx_model({"o": raw}, n_inputs=2))
        with pytest.raises(ModelError, match="must be 4-D"):
            OnnxDetector(onnx_model({"o": raw}, input_shape=(1, 3, 416)))
        with pytest.raises(ModelError, match="fixed batch size 4"):
            OnnxDetector(onnx_model({"o": raw}, input_shape=(4, 3, 416, 416)))
        with pytest.raises(ModelError, match="has type tensor\\(int32\\)"):
            OnnxDetector(onnx_model({"o": raw}, input_type=TensorProto.INT32))


@settings(max_examples=180, deadline=None)
@given(w=st.integers(1, 700), h=st.integers(1, 700), grey=st.booleans(), centre=st.booleans())
def test_property_boxes_inside_any_image(w, h, grey, centre):
    det = _PROPERTY_DETECTORS[centre]
    dets = det.detect(_image(w, h, grey))
    assert dets.xyxy.dtype == np.float32 and dets.xyxy.shape[1] == 4
    assert np.all(dets.xyxy >= 0) and np.all(dets.xyxy[:, 0::2] <= w) and np.all(dets.xyxy[:, 1::2] <= h)
    assert np.all(dets.xyxy[:, 2] > dets.xyxy[:, 0]) and np.all(dets.xyxy[:, 3] > dets.xyxy[:, 1])
    # the box around the whole letterboxed image maps back to the whole image
    full = dets.only("bus")
    assert len(full) == 1
    np.testing.assert_allclose(full.xyxy[0], [0, 0, w, h], atol=1e-3 * max(w, h))


def _whole_input_model():
    raw = np.zeros((1, 84, 200), np.float32)
    raw[0, :4, 0] = (208, 208, 416, 416)  # the whole input, border included
    raw[0, 4 + 5, 0] = 0.9                # bus
    raw[0, :4, 1] = (100, 100, 50, 40)
    raw[0, 4 + 0, 1] = 0.5
    return onnx_model({"output0": raw})


_PROPERTY_DETECTORS = {
    True: OnnxDetector(_whole_input_model()),
    False: OnnxDetector(_whole_input_model(), preprocessing=Preprocessing(rgb=True, scale=1 / 255, centre=False)),
}


# ------------------------------------------------------------------------------ robustness of the decoders
def _family_detectors():
    raw_x, _ = _yolox_raw(TestYolox.CELLS)
    nano, _ = _nanodet_outputs(TestNanodet.CELLS)
    return {
        "yolox": OnnxDetector(onnx_model({"output": raw_x})),
        "yolov5": OnnxDetector(onnx_model({"o": np.zeros((1, 10647, 85), np.float32)})),
        "yolov8": OnnxDetector(onnx_model({"o": np.zeros((1, 84, 300), np.float32)})),
        "nanodet": OnnxDetector(onnx_model(nano, input_shape=(1, 3, 320, 320))),
        "fastestdet": OnnxDetector(onnx_model({"o": np.zeros((1, 85, 22, 22), np.float32)}, input_shape=(1, 3, 352, 352))),
        "nms": OnnxDetector(onnx_model({"o": np.zeros((1, 300, 6), np.float32)})),
    }


_FAMILY_DETECTORS = _family_detectors()


@settings(max_examples=240, deadline=None)
@given(family=st.sampled_from(sorted(_FAMILY_DETECTORS)), seed=st.integers(0, 2**32 - 1),
       spread=st.sampled_from([1.0, 10.0, 1e4, 1e30]), special=st.sampled_from([0.0, 0.001, 0.1]),
       probabilities=st.booleans())
def test_property_hostile_raw_outputs(family, seed, spread, special, probabilities):
    """Random raw tensors with NaN/inf/huge values: a valid Detections or ModelError about the scores, never a crash."""
    det = _FAMILY_DETECTORS[family]
    rng = np.random.default_rng(seed)
    outputs = []
    for out in det.session.get_outputs():
        shape = tuple(out.shape)
        if probabilities:
            arr = rng.random(shape).astype(np.float32)
            arr[..., :4] *= spread
        else:
            arr = rng.normal(0, spread, shape).astype(np.float32)
        hits = rng.random(shape) < special
        arr[hits] = rng.choice(np.float32([np.nan, np.inf, -np.inf, 3e38]), int(hits.sum()))
        outputs.append(arr)
    _, lb = det.preprocess(_image(97, 41))
    try:
        dets = det.postprocess(outputs, lb)
    except ModelError as exc:
        assert "expected probabilities in [0, 1]" in str(exc)
        return
    assert np.all(np.isfinite(dets.xyxy)) and np.all(dets.xyxy[:, 0::2] <= 97) and np.all(dets.xyxy[:, 1::2] <= 41)
    assert len(dets) <= det.max_detections


def test_nanodet_plus_single_output():
    s, gx, gy = 16, 4, 6  # stride-16 level starts after the 40 x 40 stride-8 cells
    raw = np.full((1, 2125, 80 + 32), -1e4, np.float32)
    raw[:, :, :80] = 0.0
    idx = 1600 + gy * 20 + gx
    raw[0, idx, 80 + np.array([2, 8 + 3, 16 + 1, 24 + 0])] = 0.0  # one-hot distances 2, 3, 1, 0 (x stride)
    raw[0, idx, 14] = 0.8                                        # bird
    det = OnnxDetector(onnx_model({"output": raw}, input_shape=(1, 3, 320, 320)))
    assert det.family == "nanodet_plus" and det.layout.reg_max == 7
    cx, cy = gx * s, gy * s  # NanoDet-Plus priors sit on the cell corner
    expected_in = np.array([[cx - 2 * s, cy - 3 * s, cx + 1 * s, cy + 0 * s]])
    dets = det.detect(_image(640, 480))
    assert dets.labels == ["bird"]
    np.testing.assert_array_equal(dets.xyxy, _centre_to_orig(expected_in, 40, 2.0))


@pytest.mark.parametrize("kind", ["yolov7_k7", "dets_labels"])
def test_other_nms_included_layouts(kind):
    if kind == "yolov7_k7":  # batch_id, x1, y1, x2, y2, class, score
        raw = np.zeros((3, 7), np.float32)
        raw[:, 1:5] = BOXES_IN
        raw[:, 5] = CLASSES
        raw[:, 6] = SCORES
        outs = {"output": raw}
    else:  # mmdetection: dets (1, K, 5) x1 y1 x2 y2 score + labels (1, K)
        dets_arr = np.zeros((1, 3, 5), np.float32)
        dets_arr[0, :, :4] = BOXES_IN
        dets_arr[0, :, 4] = SCORES
        outs = {"dets": dets_arr, "labels": np.array([CLASSES], np.int64)}
    det = OnnxDetector(onnx_model(outs))
    assert det.family == "nms"
    dets = _sorted(det.detect(_image(832, 624)))
    assert dets.labels == [COCO_CLASSES[c] for c in CLASSES]
    np.testing.assert_array_equal(dets.xyxy, _centre_to_orig(BOXES_IN, 52, 2.0))


def test_old_yolov5_export_with_extra_level_outputs():
    n = 3 * grid_count(416, 416, (8, 16, 32))
    raw = np.zeros((1, n, 85), np.float32)
    raw[0, 7, :5] = (208, 208, 100, 50, 0.9)
    raw[0, 7, 5 + 2] = 1.0
    outs = {"output": raw, "345": np.zeros((1, 3, 52, 52, 85), np.float32), "403": np.zeros((1, 3, 26, 26, 85), np.float32)}
    det = OnnxDetector(onnx_model(outs))
    assert det.family == "yolov5" and det.layout.outputs == (0,)
    dets = det.detect(_image(416, 416))
    assert dets.labels == ["car"]
    np.testing.assert_array_equal(dets.xyxy, np.float32([[158, 183, 258, 233]]))
