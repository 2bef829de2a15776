"""Tiny ONNX stereo networks built with onnx.helper, for the benchmarks' ONNX stereo harness tests (test helper)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper

OPSET = [helper.make_opsetid("", 13)]


def _int64(name: str, values: list[int]) -> onnx.TensorProto:
    return helper.make_tensor(name, TensorProto.INT64, [len(values)], values)


def build_sad_wta(path: Path, num_disparities: int, *, metadata: dict[str, str] | None = None) -> Path:
    """A real (if naive) stereo network: per-pixel absolute difference over channels, 3x3 box filter,
    winner-takes-all over ``num_disparities`` shifts of the right image. Dynamic H and W."""
    nodes, inits, costs = [], [_int64("axes_w", [3]), _int64("axes_c", [1])], []
    for d in range(num_disparities):
        if d == 0:
            shifted = "right"
        else:
            inits += [_int64(f"pads{d}", [0, 0, 0, d, 0, 0, 0, 0]), _int64(f"st{d}", [0]), _int64(f"en{d}", [-d])]
            nodes.append(helper.make_node("Pad", ["right", f"pads{d}"], [f"padded{d}"], mode="edge"))
            nodes.append(helper.make_node("Slice", [f"padded{d}", f"st{d}", f"en{d}", "axes_w"], [f"shift{d}"]))
            shifted = f"shift{d}"
        nodes.append(helper.make_node("Sub", ["left", shifted], [f"diff{d}"]))
        nodes.append(helper.make_node("Abs", [f"diff{d}"], [f"ad{d}"]))
        nodes.append(helper.make_node("ReduceSum", [f"ad{d}", "axes_c"], [f"sum{d}"], keepdims=1))
        nodes.append(helper.make_node("AveragePool", [f"sum{d}"], [f"cost{d}"], kernel_shape=[3, 3], pads=[1, 1, 1, 1],
                                      count_include_pad=0))
        costs.append(f"cost{d}")
    nodes.append(helper.make_node("Concat", costs, ["volume"], axis=1))
    nodes.append(helper.make_node("ArgMin", ["volume"], ["winner"], axis=1, keepdims=0))
    nodes.append(helper.make_node("Cast", ["winner"], ["disparity"], to=TensorProto.FLOAT))
    shape = [1, 3, "H", "W"]
    graph = helper.make_graph(
        nodes, "sad_wta",
        [helper.make_tensor_value_info("left", TensorProto.FLOAT, shape), helper.make_tensor_value_info("right", TensorProto.FLOAT, shape)],
        [helper.make_tensor_value_info("disparity", TensorProto.FLOAT, [1, "H", "W"])],
        initializer=inits,
    )
    model = helper.make_model(graph, opset_imports=OPSET, ir_version=8)
    for k, v in (metadata or {}).items():
        model.metadata_props.append(onnx.StringStringEntryProto(key=k, value=v))
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def build_constant(path: Path, value: float, *, width: int, height: int, metadata: dict[str, str] | None = None, channels: int = 3) -> Path:
    """Static-size model whose output is ``value`` everywhere: (left - left) summed over channels + value."""
    inits = [_int64("axes_c", [1]), helper.make_tensor("val", TensorProto.FLOAT, [], [value])]
    nodes = [
        helper.make_node("Sub", ["left", "left"], ["zero"]),
        helper.make_node("Sub", ["right", "right"], ["zero_r"]),
        helper.make_node("Add", ["zero", "zero_r"], ["zeros"]),
        helper.make_node("ReduceSum", ["zeros", "axes_c"], ["plane"], keepdims=1),
        helper.make_node("Add", ["plane", "val"], ["disparity"]),
    ]
    shape = [1, channels, height, width]
    graph = helper.make_graph(
        nodes, "constant",
        [helper.make_tensor_value_info("left", TensorProto.FLOAT, shape), helper.make_tensor_value_info("right", TensorProto.FLOAT, shape)],
        [helper.make_tensor_value_info("disparity", TensorProto.FLOAT, [1, 1, height, width])],
        initializer=inits,
    )
    model = helper.make_model(graph, opset_imports=OPSET, ir_version=8)
    for k, v in (metadata or {}).items():
        model.metadata_props.append(onnx.StringStringEntryProto(key=k, value=v))
    onnx.save(model, str(path))
    return path


def textured_pair(shift: int, *, height: int = 40, width: int = 72, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Random texture; the right view is the left shifted so that every pixel has disparity ``shift``."""
    rng = np.random.default_rng(seed)
    left = rng.integers(0, 256, size=(height, width + shift, 3), dtype=np.uint8)
    right = np.ascontiguousarray(left[:, shift:])            # right[x] = left[x + d]
    return np.ascontiguousarray(left[:, :width]), np.ascontiguousarray(right[:, :width])
