"""Tiny ONNX feature networks built with onnx.helper, for the learned-cost tests (test helper).

``build_conv_features`` is a real (if naive) Siamese feature network: one 3x3 convolution without padding (margin 1)
with fixed random zero-mean weights (blind to a brightness offset), C channels, no activation: what
``SGMParams(cost="features")`` runs. ``build_divided_features`` ends it with a division (MC-CNN ends with its L2
norm). The other builders make the broken networks the matcher must refuse with one clear line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import onnx
from onnx import TensorProto, helper

OPSET = [helper.make_opsetid("", 13)]


def _save(nodes, inputs, outputs, inits, path: Path) -> Path:
    graph = helper.make_graph(nodes, "features", inputs, outputs, initializer=inits)
    model = helper.make_model(graph, opset_imports=OPSET, ir_version=8)
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def build_conv_features(path: Path, *, channels: int = 8, rank: int = 4, kernel: int = 3, seed: int = 0) -> Path:
    """Input (1, 1, H, W) (rank 4), (1, H, W) (rank 3) or (H, W) (rank 2), float32; output (1, C, H - k + 1,
    W - k + 1) for rank 4, else (C, H - k + 1, W - k + 1): a ``kernel`` x ``kernel`` convolution, no padding."""
    weights = np.random.default_rng(seed).standard_normal((channels, 1, kernel, kernel))
    weights = (weights - weights.mean(axis=(2, 3), keepdims=True)).astype(np.float32)  # blind to the brightness
    inits = [helper.make_tensor("w", TensorProto.FLOAT, weights.shape, weights.ravel().tolist()),
             helper.make_tensor("shape4", TensorProto.INT64, [4], [1, 1, -1, 0])]
    nodes, x = [], "image"
    in_shape = [1, 1, "H", "W"][4 - rank:]
    if rank != 4:
        inits.append(helper.make_tensor("axes", TensorProto.INT64, [4 - rank], list(range(4 - rank))))
        nodes.append(helper.make_node("Unsqueeze", ["image", "axes"], ["image4"]))
        x = "image4"
    nodes.append(helper.make_node("Conv", [x, "w"], ["conv"]))
    out_shape = [1, channels, "Ho", "Wo"]
    if rank != 4:
        inits.append(helper.make_tensor("axis0", TensorProto.INT64, [1], [0]))
        nodes.append(helper.make_node("Squeeze", ["conv", "axis0"], ["features"]))
        out_shape = out_shape[1:]
    else:
        nodes.append(helper.make_node("Identity", ["conv"], ["features"]))
    return _save(nodes, [helper.make_tensor_value_info("image", TensorProto.FLOAT, in_shape)],
                 [helper.make_tensor_value_info("features", TensorProto.FLOAT, out_shape)], inits, path)


def build_rank5_input(path: Path) -> Path:
    """Input of rank 5 (1, 1, 1, H, W): not a grey image."""
    nodes = [helper.make_node("Identity", ["image"], ["features"])]
    return _save(nodes, [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 1, 1, "H", "W"])],
                 [helper.make_tensor_value_info("features", TensorProto.FLOAT, [1, 1, 1, "H", "W"])], [], path)


def build_strided_features(path: Path) -> Path:
    """A 2x2 convolution with stride 2: features at half the resolution, not (C, H - 2m, W - 2m)."""
    weights = np.ones((4, 1, 2, 2), np.float32)
    inits = [helper.make_tensor("w", TensorProto.FLOAT, weights.shape, weights.ravel().tolist())]
    nodes = [helper.make_node("Conv", ["image", "w"], ["features"], strides=[2, 2])]
    return _save(nodes, [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 1, "H", "W"])],
                 [helper.make_tensor_value_info("features", TensorProto.FLOAT, [1, 4, "Ho", "Wo"])], inits, path)


def build_nan_features(path: Path) -> Path:
    """Features log(image - 1e9): NaN everywhere (the log of a negative number)."""
    inits = [helper.make_tensor("big", TensorProto.FLOAT, [], [1e9])]
    nodes = [helper.make_node("Sub", ["image", "big"], ["neg"]), helper.make_node("Log", ["neg"], ["features"])]
    return _save(nodes, [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 1, "H", "W"])],
                 [helper.make_tensor_value_info("features", TensorProto.FLOAT, [1, 1, "H", "W"])], inits, path)


def build_divided_features(path: Path, *, divisor: str = "norm", channels: int = 8, seed: int = 0) -> Path:
    """``build_conv_features``' (1, C, H - 2, W - 2) convolution, then divided, then squeezed to (C, H - 2, W - 2).

    ``divisor``: "norm", each pixel's vector by its L2 norm (``ReduceL2`` over the channels, ``Clip`` at 1e-12, MC-CNN's
    end); "constant", by 2 (the same unit vectors); "per_channel", channel c by c + 1 (not the same unit vectors)."""
    weights = np.random.default_rng(seed).standard_normal((channels, 1, 3, 3))
    weights = (weights - weights.mean(axis=(2, 3), keepdims=True)).astype(np.float32)
    inits = [helper.make_tensor("w", TensorProto.FLOAT, weights.shape, weights.ravel().tolist()),
             helper.make_tensor("axis0", TensorProto.INT64, [1], [0]),
             helper.make_tensor("unused", TensorProto.FLOAT, [2], [1.0, 2.0])]
    nodes = [helper.make_node("Conv", ["image", "w"], ["conv"])]
    if divisor == "norm":
        inits.append(helper.make_tensor("eps", TensorProto.FLOAT, [], [1e-12]))
        nodes += [helper.make_node("ReduceL2", ["conv"], ["norm"], axes=[1], keepdims=1),
                  helper.make_node("Clip", ["norm", "eps"], ["den"])]
    elif divisor == "constant":
        inits.append(helper.make_tensor("den", TensorProto.FLOAT, [], [2.0]))
    else:
        inits.append(helper.make_tensor("den", TensorProto.FLOAT, [1, channels, 1, 1],
                                        [float(c + 1) for c in range(channels)]))
    nodes += [helper.make_node("Div", ["conv", "den"], ["unit"]),
              helper.make_node("Squeeze", ["unit", "axis0"], ["features"])]
    return _save(nodes, [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 1, "H", "W"])],
                 [helper.make_tensor_value_info("features", TensorProto.FLOAT, [channels, "Ho", "Wo"])], inits, path)
