"""Learned matching costs: a Siamese feature network (ONNX) in front of the same semi-global matcher.

A feature network maps one grey image to a C-vector per pixel; the cost of matching left pixel x with right pixel
x - d is ``FEATURE_SCALE * (1 - <fL(x), fR(x - d)>)`` of the unit vectors (or their scaled L1 distance), computed a
row at a time by the kernels (``_kernels.cost.feature_row_cost``) from int8 copies of the features, then aggregated,
checked and filled like the classical costs. The package ships MC-CNN "fast" (Zbontar & LeCun 2016; CNES's
``mccnn`` 1.4.1 wheel, Apache-2.0: ``data/PROVENANCE.md``); ``SGMParams.feature_model`` takes any other network.

What a network must be (checked when it is loaded, one clear line otherwise): an ONNX file with one float32 input,
a grey image of rank 2 (H, W), 3 (1, H, W) or 4 (1, 1, H, W) with free H and W, and one output (C, H - 2m, W - 2m)
(or (1, C, H - 2m, W - 2m)): features centred on the input pixels, m >= 0 the margin a network without padding
loses (MC-CNN fast: 5). The input is padded by m (replicated borders) so that every pixel gets a feature.

>>> from stereo_classic.matching.learned import shipped_model_path
>>> shipped_model_path("mccnn-fast-dw").name
'mc_cnn_fast_dw.onnx'
"""

from __future__ import annotations

import os
import threading
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from detectors.errors import first_line
from detectors.models import verify_sha256
from detectors.onnx_wire import pb_encode, pb_fields, pb_strings
from stereo_classic.matching._kernels.features import quantise_rows
from stereo_classic.matching._kernels.workers import run_tasks

__all__ = ["FeatureModel", "FeatureModelError", "SHIPPED_MODELS", "DEFAULT_MCCNN", "FEATURE_INPUTS", "PROVIDERS",
           "feature_model", "model_for", "memory_terms", "shipped_model_path", "onnx_feature_bytes", "ORT_PEAK_FACTOR"]

_DATA = Path(__file__).with_name("data")


@dataclass(frozen=True)
class ShippedModel:
    """A feature network in ``stereo_classic/matching/data``: its file and sha256."""

    file: str
    sha256: str


#: The feature networks shipped as package data (``data/PROVENANCE.md``: where they come from, their licence).
SHIPPED_MODELS = {
    "mccnn-fast-dw": ShippedModel("mc_cnn_fast_dw.onnx",
                                  "2803ce5d6d3d947a482ed671bbfd18186fc079075190e93ff8abb2c0706ee90b"),
    "mccnn-fast-int8": ShippedModel("mc_cnn_fast_int8_excl_01.onnx",
                                    "eeb9d7d0ab8023dbf6ffac25d170b9405d0d57101c3e81312bd61c10448cf544"),
}
#: The network of ``cost="mccnn"`` when ``feature_model`` is None: the depthwise-separable fast net (half the time of
#: the paper's fast net in int8 on 2 cores, measured: 0.115 against 0.29 s per 1242 x 375 image, both without their
#: final normalisation, ``without_final_division``).
DEFAULT_MCCNN = "mccnn-fast-dw"
#: Input normalisations: per image ``(I - mean) / std`` (MC-CNN's), ``I / 255``, or the grey levels as they are.
FEATURE_INPUTS = ("standardize", "unit", "raw")
#: ONNX Runtime execution providers: "cpu", "cuda" (refused where this onnxruntime has none), "auto" (CUDA when
#: available, else CPU).
PROVIDERS = ("cpu", "cuda", "auto")
#: ONNX Runtime's peak while a feature network runs, in units of its float32 output: 3.5 measured for both shipped
#: MC-CNN nets at 1252 x 385 (maximum RSS); 4 with a margin. A deeper network may need more.
ORT_PEAK_FACTOR = 4
# The probe the output's shape is checked on (height, width): small, not square, not a power of two.
_PROBE = (48, 40)


class FeatureModelError(ValueError):
    """A feature network that cannot be used: not ONNX, wrong input, output not (C, H', W'), non-finite features."""


def shipped_model_path(name: str) -> Path:
    """The file of a shipped feature network (``SHIPPED_MODELS``)."""
    return _DATA / SHIPPED_MODELS[name].file


def resolve(model: str | os.PathLike) -> Path:
    """The file of ``model``: a shipped network's name or a path; FeatureModelError when there is none."""
    if isinstance(model, str) and model in SHIPPED_MODELS:
        path = shipped_model_path(model)
        if not path.is_file():
            raise FeatureModelError(f"`feature_model` {model!r}: the shipped file {path} is missing (broken install)")
        return path
    path = Path(model).expanduser()
    if not path.is_file():
        raise FeatureModelError(f"`feature_model` must be an ONNX file or one of {', '.join(SHIPPED_MODELS)}, "
                                f"got {str(model)!r} (no such file)")
    return path


def _providers(provider: str) -> list[str]:
    import onnxruntime as ort

    available = ort.get_available_providers()
    cuda = "CUDAExecutionProvider" in available
    if provider == "cuda" and not cuda:
        raise FeatureModelError(f"`onnx_provider` 'cuda': this onnxruntime has no CUDAExecutionProvider (available: "
                                f"{', '.join(available)}); install onnxruntime-gpu or use 'cpu' / 'auto'")
    if provider in ("cuda", "auto") and cuda:
        return ["CUDAExecutionProvider", "CPUExecutionProvider"]
    return ["CPUExecutionProvider"]


#: Operators that only change a tensor's rank, walked over from the output back to a final division.
_RANK_OPS = ("Squeeze", "Unsqueeze", "Identity")


def _unit(features: np.ndarray) -> np.ndarray:
    """Each pixel's (C, H, W) feature vector at unit length (a zero vector stays zero), in float64."""
    f = features.astype(np.float64)
    norm = np.sqrt((f * f).sum(axis=0))
    return f / np.where(norm > 0, norm, 1.0)


def without_final_division(data: bytes) -> tuple[bytes, str] | None:
    """The serialized model ending before its final division, and the divided tensor's name; None where the output
    is not a division (``Div``, behind rank-only operators at most).

    A feature network that ends by dividing its features by their own L2 norm (MC-CNN's ``x / max(||x||, eps)``)
    repeats what ``features`` does to every pixel's vector anyway (``quantise_rows`` normalises it), so the division
    and everything that only feeds its denominator (the norm, its reshapes) are work for nothing: a quarter to a
    third of the shipped MC-CNN's ONNX time (measured, median of 7 runs on a 1252 x 385 image, 2 threads: the
    depthwise net 169 -> 115 ms, the int8 one 376 -> 288 ms). The rewrite keeps the graph's first output only, the
    numerator's name as that output (its type float, shape unknown), the nodes it needs and the initializers they
    read (``value_info`` dropped, for ONNX Runtime to infer it); every kept node and initializer is copied byte for
    byte. Whether it gives the same unit vectors is for the caller to check (a division
    by anything else is not redundant): ``FeatureModel`` compares both on its probe image and keeps the original
    where they differ.
    """
    model = pb_fields(data)
    gi = next((i for i, (num, wire, _) in enumerate(model) if num == 7 and wire == 2), None)  # ModelProto.graph
    if gi is None:
        return None
    graph = pb_fields(model[gi][2])
    nodes = [(pb_fields(raw), raw) for num, wire, raw in graph if num == 1 and wire == 2]  # GraphProto.node
    outputs = [pb_strings(pb_fields(raw), 1) for num, wire, raw in graph if num == 12 and wire == 2]
    if not outputs or not outputs[0]:
        return None
    producer = {}
    for k, (fields, _) in enumerate(nodes):  # NodeProto: input 1, output 2, op_type 4
        for name in pb_strings(fields, 2):
            producer[name] = k

    def op_of(tensor: str) -> str | None:
        ops = pb_strings(nodes[producer[tensor]][0], 4) if tensor in producer else []
        return ops[0] if ops else None

    def inputs_of(tensor: str) -> list[str]:  # of the node that makes ``tensor`` (one is known to)
        return pb_strings(nodes[producer[tensor]][0], 1)

    name = outputs[0][0]
    while op_of(name) in _RANK_OPS and inputs_of(name):
        name = inputs_of(name)[0]
    if op_of(name) != "Div" or len(inputs_of(name)) != 2:
        return None
    numerator = inputs_of(name)[0]
    keep, todo = set(), [numerator]
    while todo:  # the nodes the numerator needs
        k = producer.get(todo.pop())
        if k is not None and k not in keep:
            keep.add(k)
            todo.extend(pb_strings(nodes[k][0], 1))
    read = {inp for k in keep for inp in pb_strings(nodes[k][0], 1)}
    out_info = pb_encode([(1, 2, numerator.encode()), (2, 2, pb_encode([(1, 2, pb_encode([(1, 0, b"\x01")]))]))])
    new_graph, k, first_output = [], 0, True
    for num, wire, raw in graph:
        if num == 1 and wire == 2:  # nodes: the kept ones, in order
            if k in keep:
                new_graph.append((num, wire, raw))
            k += 1
        elif num == 5 and wire == 2:  # initializers (TensorProto.name: 8): those a kept node reads
            if set(pb_strings(pb_fields(raw), 8)) & read:
                new_graph.append((num, wire, raw))
        elif num == 12 and wire == 2:  # outputs: the numerator, float (TypeProto.tensor_type 1, elem_type 1)
            if first_output:
                new_graph.append((num, wire, out_info))
                first_output = False
        elif num != 13:  # value_info: dropped
            new_graph.append((num, wire, raw))
    model[gi] = (7, 2, pb_encode(new_graph))
    return pb_encode(model), numerator


class FeatureModel:
    """A Siamese feature network loaded and checked once: ``features(left, right, ...)`` gives the int8 pair the
    kernels read.

    Parameters
    ----------
    model : str or path
        A shipped network's name (``SHIPPED_MODELS``) or an ONNX file.
    provider : {"cpu", "cuda", "auto"}
        ONNX Runtime's execution provider.
    threads : int or None
        ONNX Runtime's intra-op threads (None: its default, every core).
    """

    def __init__(self, model: str | os.PathLike, *, provider: str = "cpu", threads: int | None = None) -> None:
        import onnxruntime as ort

        from detectors.onnx_detector import session_options

        self.path = resolve(model)
        self.name = str(model)
        shipped = SHIPPED_MODELS.get(model) if isinstance(model, str) else None
        if shipped is not None and not verify_sha256(self.path, shipped.sha256):
            raise FeatureModelError(f"`feature_model` {model!r}: {self.path} does not have the shipped sha256 "
                                    f"(broken install)")
        opts = session_options(threads)  # the detector's: no busy-waiting, the matcher's own threads run next
        try:
            self.session = ort.InferenceSession(str(self.path), sess_options=opts, providers=_providers(provider))
        except FeatureModelError:
            raise
        except Exception as exc:  # onnxruntime's own classes (InvalidProtobuf, Fail, ...)
            first = first_line(exc)
            raise FeatureModelError(f"`feature_model` {self.path} is not a usable ONNX model: {first[:300]}") from None
        self.providers = tuple(self.session.get_providers())
        inputs, outputs = self.session.get_inputs(), self.session.get_outputs()
        if len(inputs) != 1 or len(outputs) < 1:
            raise FeatureModelError(f"`feature_model` {self.path} must have one input (a grey image) and one output "
                                    f"(features), got {len(inputs)} inputs and {len(outputs)} outputs")
        shape = list(inputs[0].shape)
        lead = shape[:-2]
        if len(shape) not in (2, 3, 4) or any(d not in (1, None) and not isinstance(d, str) for d in lead):
            raise FeatureModelError(f"`feature_model` {self.path}: the input must be a grey image of rank 2 (H, W), "
                                    f"3 (1, H, W) or 4 (1, 1, H, W), got rank {len(shape)} {tuple(shape)}")
        if any(isinstance(d, int) for d in shape[-2:]):
            raise FeatureModelError(f"`feature_model` {self.path}: the input's height and width must be free "
                                    f"(dynamic axes), got {tuple(shape)}")
        if inputs[0].type != "tensor(float)":
            raise FeatureModelError(f"`feature_model` {self.path}: the input must be float32, got {inputs[0].type}")
        self._input = inputs[0].name
        self._output = outputs[0].name
        self._rank = len(shape)
        probe = np.random.default_rng(0).standard_normal(_PROBE).astype(np.float32)
        out = self._run(probe, check=True)
        self.skipped_division = self._skip_final_division(ort, opts, provider, probe, out)
        self.channels = int(out.shape[0])
        self.margin = (_PROBE[0] - out.shape[1]) // 2

    def _skip_final_division(self, ort, opts, provider: str, probe: np.ndarray, out: np.ndarray) -> str | None:
        """Run the network without its final division where that gives the same unit vectors on the probe
        (``without_final_division``); the divided tensor's name, or None (the network as it is)."""
        cut = without_final_division(self.path.read_bytes())
        if cut is None:
            return None
        original = (self.session, self._output)
        try:
            self.session = ort.InferenceSession(cut[0], sess_options=opts, providers=_providers(provider))
            self._output = self.session.get_outputs()[0].name
            cut_out = self._run(probe, check=True)
        except Exception:  # not a network ONNX Runtime runs without its end: keep it whole
            cut_out = None
        if cut_out is not None and cut_out.shape == out.shape:
            a, b = _unit(out), _unit(cut_out)
            if np.isfinite(b).all() and float(np.abs(a - b).max()) <= 1e-5:
                return cut[1]
        self.session, self._output = original
        return None

    def _run(self, image: np.ndarray, *, check: bool = False) -> np.ndarray:
        """The network's (C, H', W') float32 output for one normalised (H, W) float32 image."""
        x = image.reshape((1,) * (self._rank - 2) + image.shape)
        try:
            out = self.session.run([self._output], {self._input: x})[0]
        except Exception as exc:
            first = first_line(exc)
            raise FeatureModelError(f"`feature_model` {self.path} failed on a {image.shape[0]} x {image.shape[1]} "
                                    f"image: {first[:300]}") from None
        out = np.asarray(out)
        if out.ndim == 4 and out.shape[0] == 1:
            out = out[0]
        H, W = image.shape
        dh, dw = (H - out.shape[1], W - out.shape[2]) if out.ndim == 3 else (-1, -1)
        if out.ndim != 3 or out.shape[0] < 1 or dh < 0 or dh != dw or dh % 2 or out.dtype != np.float32:
            raise FeatureModelError(
                f"`feature_model` {self.path}: the output must be float32 features (C, H - 2m, W - 2m) centred on "
                f"the input pixels (m >= 0), got {out.dtype} {tuple(out.shape)} for an input of {H} x {W}")
        if check and not np.isfinite(out).all():
            raise FeatureModelError(f"`feature_model` {self.path} gives features that are not finite "
                                    f"(NaN or inf) on a test image")
        return out

    def feature_bytes(self, height: int, width: int) -> int:
        """Bytes ``features`` needs for a pair of this size beyond the kernels': the padded float32 input, ONNX
        Runtime's peak (``ORT_PEAK_FACTOR`` times its float32 output) and the row scratch."""
        return onnx_feature_bytes(height, width, self.channels, self.margin)

    def features(self, left: np.ndarray, right: np.ndarray, *, normalisation: str = "standardize",
                 threads: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """The int8 unit feature vectors of a uint8 grey pair: (H, C, W) each (one image row per channel).

        Each image is normalised on its own (``FEATURE_INPUTS``), padded by the margin, run through the network,
        and quantised on ``threads`` workers. FeatureModelError when a feature is not finite.
        """
        out = []
        for side, img in (("left", left), ("right", right)):
            x = img.astype(np.float32)
            if normalisation == "standardize":  # MC-CNN's own: (I - mean) / std per image, std 0 -> 1
                std = float(x.std())
                x -= float(x.mean())
                x /= std if std > 0 else 1.0
            elif normalisation == "unit":
                x /= 255.0
            elif normalisation != "raw":
                raise ValueError(f"`feature_input` must be one of {', '.join(FEATURE_INPUTS)}, got {normalisation!r}")
            m = self.margin
            if m:
                x = cv2.copyMakeBorder(x, m, m, m, m, cv2.BORDER_REPLICATE)
            feat = self._run(x)
            H, W = img.shape
            C = feat.shape[0]
            if feat.shape[1:] != (H, W):  # the margin holds for every size (checked on the probe)
                raise FeatureModelError(f"`feature_model` {self.path}: output {tuple(feat.shape)} for a padded "
                                        f"{x.shape[0]} x {x.shape[1]} input; expected ({C}, {H}, {W})")
            q = np.empty((H, C, W), np.int8)
            bands = [(y0, min(H, y0 + 32)) for y0 in range(0, H, 32)]
            n = max(1, min(int(threads), len(bands)))
            scratch = [np.empty(W, np.float64) for _ in range(n)]
            bad = run_tasks(bands, n, lambda t, b, f=feat, q=q: quantise_rows(f, 0, b[0], b[1], q, scratch[t]))
            if sum(bad):
                raise FeatureModelError(f"`feature_model` {self.path} gives features that are not finite (NaN or inf)"
                                        f" at {sum(bad)} pixels of the {side} image")
            del feat
            out.append(q)
        return out[0], out[1]


def onnx_feature_bytes(height: int, width: int, channels: int, margin: int) -> int:
    """Bytes of the feature step beyond the kernels' int8 features: the padded float32 input and ONNX Runtime's peak
    for one image at a time (``ORT_PEAK_FACTOR`` times its float32 output)."""
    Hp, Wp = int(height) + 2 * int(margin), int(width) + 2 * int(margin)
    return 2 * 4 * Hp * Wp + ORT_PEAK_FACTOR * 4 * int(channels) * int(height) * int(width)


def model_for(params) -> FeatureModel:
    """The loaded feature network of an ``SGMParams`` with a learned cost (``feature_model``)."""
    return feature_model(params.effective_feature_model, params.onnx_provider, params.effective_threads)


def memory_terms(params, height: int, width: int) -> tuple[int, int]:
    """(channels, bytes) of a learned cost for ``estimate_memory``: the network's channel count (the kernels count
    the int8 features) and ``FeatureModel.feature_bytes``; (0, 0) for a classical cost."""
    if not params.learned:
        return 0, 0
    model = model_for(params)
    return model.channels, model.feature_bytes(height, width)


_MODELS: dict[tuple, FeatureModel] = {}
_MODELS_LOCK = threading.Lock()


def feature_model(model: str | os.PathLike, provider: str = "cpu", threads: int | None = None) -> FeatureModel:
    """The loaded ``FeatureModel`` (one per file, provider and thread count, kept for the process)."""
    path = resolve(model)
    key = (str(model), str(path.resolve()), path.stat().st_mtime_ns, provider, threads)
    with _MODELS_LOCK:
        loaded = _MODELS.get(key)
        if loaded is None:
            loaded = _MODELS[key] = FeatureModel(model, provider=provider, threads=threads)
        return loaded
