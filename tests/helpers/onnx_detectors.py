"""Tiny ONNX detector models whose outputs are constants (test helper, no API)."""

from __future__ import annotations

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper


def constant_detector(outputs: dict[str, np.ndarray], *, input_shape=(1, 3, 416, 416),
                      metadata: dict[str, str] | None = None) -> bytes:
    """Serialized ONNX model: one float image input ``images`` (unused), outputs = the given constants."""
    nodes, outs = [], []
    for name, arr in outputs.items():
        nodes.append(helper.make_node("Constant", [], [name], value=numpy_helper.from_array(arr, f"{name}_value")))
        outs.append(helper.make_tensor_value_info(name, helper.np_dtype_to_tensor_dtype(arr.dtype), list(arr.shape)))
    inputs = [helper.make_tensor_value_info("images", TensorProto.FLOAT, list(input_shape))]
    model = helper.make_model(helper.make_graph(nodes, "tiny", inputs, outs),
                              opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    if metadata:
        helper.set_model_props(model, metadata)
    onnx.checker.check_model(model)
    return model.SerializeToString()


def shape_echo_detector(num_classes: int = 80, *, metadata: dict[str, str] | None = None) -> bytes:
    """A dynamic-size ONNX model whose (1, 4 + C, 100) YOLOv8-style output holds one box ``(W/2, H/2, W/2, H/2)``
    (xywh, class 0, score 0.9; the 99 other anchors are zeros) computed from the input's own height H and
    width W: it shows which input size the detector fed it."""
    shape = helper.make_node("Shape", ["images"], ["shape"])
    hw = helper.make_node("Gather", ["shape", "idx"], ["hw"], axis=0)  # (H, W) int64
    f = helper.make_node("Cast", ["hw"], ["hwf"], to=TensorProto.FLOAT)
    wh = helper.make_node("Gather", ["hwf", "rev"], ["whf"], axis=0)  # (W, H)
    half = helper.make_node("Mul", ["whf", "half"], ["c"])
    box = helper.make_node("Concat", ["c", "c", "tail"], ["flat"], axis=0)  # cx cy w h, scores
    col = helper.make_node("Reshape", ["flat", "oshape"], ["col"])
    out = helper.make_node("Concat", ["col", "zeros"], ["output0"], axis=2)
    tail = np.zeros(num_classes, np.float32)
    tail[0] = 0.9
    inits = [numpy_helper.from_array(np.array([2, 3], np.int64), "idx"),
             numpy_helper.from_array(np.array([1, 0], np.int64), "rev"),
             numpy_helper.from_array(np.array([0.5, 0.5], np.float32), "half"),
             numpy_helper.from_array(tail, "tail"),
             numpy_helper.from_array(np.array([1, 4 + num_classes, 1], np.int64), "oshape"),
             numpy_helper.from_array(np.zeros((1, 4 + num_classes, 99), np.float32), "zeros")]
    graph = helper.make_graph(
        [shape, hw, f, wh, half, box, col, out], "echo",
        [helper.make_tensor_value_info("images", TensorProto.FLOAT, [1, 3, "height", "width"])],
        [helper.make_tensor_value_info("output0", TensorProto.FLOAT, [1, 4 + num_classes, 100])], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    if metadata:
        helper.set_model_props(model, metadata)
    onnx.checker.check_model(model)
    return model.SerializeToString()
