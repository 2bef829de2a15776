"""``OnnxDetector``: run an exported ONNX object detector with onnxruntime on one image."""

from __future__ import annotations

import ast
import logging
import os
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import cv2
import numpy as np

from detectors.classes import COCO_CLASSES, coerce_names, names_from_metadata, read_names_file
from detectors.decoders import FAMILIES, PREPROCESSING, OutputLayout, decode, recognise_layout
from detectors.errors import InputSizeError, ModelError, first_line
from detectors.letterbox import Letterbox, Preprocessing, check_image, letterbox
from detectors.models import resolve_model
from detectors.nms import nms
from detectors.onnx_wire import Field as _Field
from detectors.onnx_wire import pb_encode as _pb_encode
from detectors.onnx_wire import pb_fields as _pb_fields
from detectors.onnx_wire import pb_strings as _pb_strings
from detectors.results import Detections

__all__ = ["OnnxDetector", "session_options"]

log = logging.getLogger(__name__)

_INPUT_DTYPES = {"tensor(float)": np.float32, "tensor(float16)": np.float16, "tensor(uint8)": np.uint8}
_OUTPUT_DTYPES = {"tensor(float)": np.float32, "tensor(float16)": np.float16, "tensor(double)": np.float64,
                  "tensor(int64)": np.int64, "tensor(int32)": np.int32, "tensor(uint8)": np.uint8}
_MAX_CANDIDATES = 30000


def session_options(threads: int | None = None):
    """ONNX Runtime session options for a network run inside the pipeline: quiet logs, full graph optimisation,
    sequential execution with one inter-op thread, ``threads`` intra-op threads (None: ONNX Runtime's default), and
    no busy-waiting between runs (onnxruntime's worker threads spin for the next run by default; in a pipeline the
    stereo matcher runs next, and spinning threads would take its cores). Used by :class:`OnnxDetector` and by the
    matcher's learned costs."""
    import onnxruntime as ort

    opts = ort.SessionOptions()
    opts.log_severity_level = 3
    opts.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    opts.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    opts.inter_op_num_threads = 1
    if threads is not None:
        opts.intra_op_num_threads = int(threads)
    opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
    return opts


def _check_unit(value: object, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not 0.0 <= float(value) <= 1.0:
        raise ValueError(f"`{name}` must be a number in [0, 1], got {value!r}")
    return float(value)


def _static(dim: object) -> int | None:
    return int(dim) if isinstance(dim, (int, np.integer)) and int(dim) > 0 else None


def _free_image_dims(source: str | bytes, input_name: str, axes: tuple[int, int]) -> bytes:
    """The serialized model with the height and width axes of its input ``input_name`` declared free (named
    ``height`` and ``width``), its outputs' sizes unknown (their rank kept) and the shapes the export recorded for
    its inner tensors (``graph.value_info``) dropped, for ONNX Runtime to infer them again at each input size.
    Weights, operators and every other field are copied through byte for byte.

    Done on the protobuf wire format (ONNX's ``ModelProto``: graph = field 7; ``GraphProto``: input 11, output 12,
    value_info 13; ``ValueInfoProto``: name 1, type 2; ``TypeProto``: tensor_type 1; its shape 2, whose dims are
    field 1; ``Dimension``: dim_value 1, dim_param 2), not with the ``onnx`` package: importing that takes half a
    second (its ``ml_dtypes``), a start-up a camera pipeline should not pay for three fields.
    """
    data = Path(source).read_bytes() if isinstance(source, (str, os.PathLike)) else bytes(source)

    def tensor_type(value_info: bytes, edit: Callable[[list[_Field]], list[_Field]]) -> bytes:
        fields = _pb_fields(value_info)
        for i, (num, wire, raw) in enumerate(fields):
            if num == 2 and wire == 2:  # ValueInfoProto.type
                kinds = _pb_fields(raw)
                for j, (knum, kwire, kraw) in enumerate(kinds):
                    if knum == 1 and kwire == 2:  # TypeProto.tensor_type
                        kinds[j] = (knum, kwire, _pb_encode(edit(_pb_fields(kraw))))
                fields[i] = (num, wire, _pb_encode(kinds))
        return _pb_encode(fields)

    def free(tensor: list[_Field]) -> list[_Field]:
        out = []
        for num, wire, raw in tensor:
            if num == 2 and wire == 2:  # shape: its dims, the image axes renamed
                dims = _pb_fields(raw)
                where = [k for k, (dnum, dwire, _) in enumerate(dims) if dnum == 1 and dwire == 2]
                for axis, name in zip(axes, (b"height", b"width")):
                    if axis < len(where):
                        dims[where[axis]] = (1, 2, _pb_encode([(2, 2, name)]))
                raw = _pb_encode(dims)
            out.append((num, wire, raw))
        return out

    def unknown(tensor: list[_Field]) -> list[_Field]:
        return [(num, wire, _pb_encode((1, 2, b"") for dnum, _, _ in _pb_fields(raw) if dnum == 1))
                if num == 2 and wire == 2 else (num, wire, raw) for num, wire, raw in tensor]

    model = _pb_fields(data)
    for i, (num, wire, raw) in enumerate(model):
        if num != 7 or wire != 2:  # ModelProto.graph
            continue
        graph = []
        for gnum, gwire, graw in _pb_fields(raw):
            if gnum == 13:  # value_info: recorded shapes of inner tensors
                continue
            if gnum == 11 and gwire == 2 and _pb_strings(_pb_fields(graw), 1)[:1] == [input_name]:  # its name
                graw = tensor_type(graw, free)
            elif gnum == 12 and gwire == 2:  # outputs: their sizes follow the input's (the rank is kept)
                graw = tensor_type(graw, unknown)
            graph.append((gnum, gwire, graw))
        model[i] = (num, wire, _pb_encode(graph))
    return _pb_encode(model)


class OnnxDetector:
    """An exported ONNX detector (YOLOX, YOLOv5, YOLOv8/YOLO11, NanoDet, FastestDet, NMS-included).

    Parameters
    ----------
    model : str, path or bytes
        An ONNX file, a model name for :func:`detectors.resolve_model` (``"yolox_nano"``), or the
        serialized model bytes.
    conf_threshold : float in [0, 1]
        Keep boxes scoring above this (YOLOX/YOLOv5: objectness x class score).
    iou_threshold : float in [0, 1]
        Class-aware NMS overlap threshold.
    classes : iterable of str or int, optional
        Only report these classes (names or class ids).
    threads : int, optional
        onnxruntime intra-op threads (None: onnxruntime's default, all cores).
    providers : sequence of str
        onnxruntime execution providers.
    names : sequence of str or path, optional
        Class names (or a file with one name a line); default: the ONNX metadata, else COCO-80.
    family : str, optional
        Force the output decoder, one of ``detectors.decoders.FAMILIES``; default: recognised from
        the output shapes, metadata and file name (rules in :mod:`detectors.decoders`).
    input_size : int or (width, height), optional
        Input size for models with dynamic input dimensions (default: the size the model was exported
        with, metadata ``imgsz``, else 640); must match a fixed-size model.
    minimal_padding : bool
        Letterbox each image into the smallest multiple-of-32 rectangle around its resized copy (the longer
        side scaled to ``input_size``), as Ultralytics' ``predict`` does (``auto=True``), instead of padding
        it to the full square ``input_size``. Less padding to run through (a 1242x375 image becomes 640x224
        instead of 640x640; with the 416x416 YOLOX-nano, 416x128 instead of 416x416: a third of the work),
        the image at the same scale. An export with a fixed input size gets its height and width declared
        free (the graph's declared shapes rewritten in memory; weights and operators untouched); a model that
        does not run on a smaller rectangle, or gives outputs its family does not have there, is a
        ``detectors.InputSizeError`` (a ModelError).
    preprocessing : Preprocessing, optional
        Override the family's colour order, scaling, normalisation and letterbox placement.
    max_detections : int
        At most this many boxes per image, highest scores first.

    Usage (needs files that are not part of the package)::

        det = OnnxDetector("yolox_nano", threads=2)
        dets = det.detect(cv2.imread("left.png")).only("person")
    """

    def __init__(
        self,
        model: str | os.PathLike | bytes,
        *,
        conf_threshold: float = 0.3,
        iou_threshold: float = 0.45,
        classes: Iterable[str | int] | None = None,
        threads: int | None = None,
        providers: Sequence[str] = ("CPUExecutionProvider",),
        names: Sequence[str] | str | os.PathLike | None = None,
        family: str | None = None,
        input_size: int | tuple[int, int] | None = None,
        preprocessing: Preprocessing | None = None,
        max_detections: int = 300,
        minimal_padding: bool = False,
    ) -> None:
        import onnxruntime as ort

        self.conf_threshold = _check_unit(conf_threshold, "conf_threshold")
        self.iou_threshold = _check_unit(iou_threshold, "iou_threshold")
        if threads is not None and (isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1):
            raise ValueError(f"`threads` must be a positive int or None, got {threads!r}")
        if isinstance(max_detections, bool) or not isinstance(max_detections, (int, np.integer)) or max_detections < 1:
            raise ValueError(f"`max_detections` must be a positive int, got {max_detections!r}")
        if family is not None and family not in FAMILIES:
            raise ValueError(f"`family` must be one of {', '.join(FAMILIES)} or None, got {family!r}")
        if preprocessing is not None and not isinstance(preprocessing, Preprocessing):
            raise ValueError(f"`preprocessing` must be a detectors.Preprocessing, got {type(preprocessing).__name__}")
        if isinstance(providers, str) or not all(isinstance(p, str) for p in providers):
            raise ValueError(f"`providers` must be a sequence of provider names, got {providers!r}")
        available = ort.get_available_providers()
        for p in providers:
            if p not in available:
                raise ValueError(f"`providers`: {p!r} is not available in this onnxruntime; available: {', '.join(available)}")
        self.max_detections = int(max_detections)
        self.threads = threads

        if isinstance(model, (bytes, bytearray)):
            source: bytes | str = bytes(model)
            self.model_path: Path | None = None
            hint = ""
        else:
            self.model_path = resolve_model(model)
            source = str(self.model_path)
            hint = self.model_path.name
        opts = session_options(threads)
        where = self.model_path if self.model_path is not None else "<model bytes>"
        try:
            self.session = ort.InferenceSession(source, sess_options=opts, providers=list(providers))
        except Exception as exc:  # onnxruntime raises its own classes (InvalidProtobuf, Fail, ...)
            first = first_line(exc)
            raise ModelError(f"cannot load ONNX model {where}: {first[:300]}") from None
        self.metadata: dict[str, str] = dict(self.session.get_modelmeta().custom_metadata_map)

        # ---------------------------------------------------------------- input
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            raise ModelError(f"model {where} must have one image input, has {len(inputs)}: "
                             + ", ".join(f"{i.name} {i.shape}" for i in inputs))
        inp = inputs[0]
        self.input_name = inp.name
        if inp.type not in _INPUT_DTYPES:
            raise ModelError(f"model {where} input {inp.name!r} has type {inp.type}; expected float, float16 or uint8")
        self._input_dtype = _INPUT_DTYPES[inp.type]
        shape = list(inp.shape)
        if len(shape) != 4:
            raise ModelError(f"model {where} input {inp.name!r} must be 4-D (1, 3, H, W) or (1, H, W, 3), got {shape}")
        if _static(shape[0]) not in (None, 1):
            raise ModelError(f"model {where} input {inp.name!r} has fixed batch size {shape[0]}; only 1 is supported")
        if _static(shape[1]) == 3 or (_static(shape[1]) is None and _static(shape[3]) != 3):
            self.nchw = True
            hdim, wdim = shape[2], shape[3]
        elif _static(shape[3]) == 3:
            self.nchw = False
            hdim, wdim = shape[1], shape[2]
        else:
            raise ModelError(f"model {where} input {inp.name!r} has no 3-channel axis: {shape}")
        fixed = (_static(wdim), _static(hdim))
        requested = self._parse_size(input_size)
        if fixed[0] is not None and fixed[1] is not None:
            if requested is not None and requested != fixed:
                raise ValueError(f"`input_size` {requested} does not match the model's fixed input size {fixed} (width, height)")
            size = fixed
        else:
            size = requested or self._metadata_size() or (640, 640)
            if size[0] % 32 or size[1] % 32:
                raise ValueError(f"`input_size` of a dynamic-size model must be multiples of 32, got {size}")
            size = (fixed[0] or size[0], fixed[1] or size[1])
        self.input_size: tuple[int, int] = size  # (width, height)
        if not isinstance(minimal_padding, (bool, np.bool_)):
            raise ValueError(f"`minimal_padding` must be True or False, got {minimal_padding!r}")  # noqa: TRY004
        freed = bool(minimal_padding) and (fixed[0] is not None or fixed[1] is not None)
        if freed:
            # an export with a fixed size: its height and width declared free (a convolutional network runs at any
            # multiple of its stride); checked below, after the dry run, on a smaller rectangle
            axes = (2, 3) if self.nchw else (1, 2)
            try:
                self.session = ort.InferenceSession(_free_image_dims(source, inp.name, axes), sess_options=opts,
                                                    providers=list(providers))
            except Exception as exc:  # noqa: BLE001 (onnxruntime's own classes; ValueError: not a protobuf)
                first = first_line(exc)
                raise InputSizeError(f"`minimal_padding`: model {where} (fixed input size {fixed[0]}x{fixed[1]}) "
                                     f"cannot be loaded with a free input size: {first[:300]}; use "
                                     "minimal_padding=False") from None
        self.minimal_padding = bool(minimal_padding)

        # ---------------------------------------------------------------- class names given
        given_names: tuple[str, ...] | None = None
        if names is not None:
            if isinstance(names, (str, os.PathLike)):
                given_names = read_names_file(names)
            else:
                given_names = coerce_names(names, parameter="names")
        meta_names = names_from_metadata(self.metadata)
        known = given_names or meta_names

        # ---------------------------------------------------------------- outputs: a dry run
        outs = self.session.get_outputs()
        self.output_names = [o.name for o in outs]
        zeros = self._blank_input()
        try:
            raw = self.session.run(None, {self.input_name: zeros})
        except Exception as exc:
            first = first_line(exc)
            raise ModelError(f"model {where} failed on a blank {size[0]}x{size[1]} input: {first[:300]}") from None
        shapes = [np.shape(r) for r in raw]
        dtypes = [np.asarray(r).dtype for r in raw]
        self.layout: OutputLayout = recognise_layout(
            self.output_names, shapes, dtypes, (size[1], size[0]), metadata=self.metadata, hint=hint,
            family=family, num_names=len(known) if known else None)
        self.family = self.layout.family

        if known is None:
            if self.layout.num_classes != 80:
                raise ModelError(f"model {where} ({self.layout.describe()}) stores no class names and is not COCO-80; "
                                 "pass names=[...] or a names file")
            known = COCO_CLASSES
        if self.family != "nms" and len(known) != self.layout.num_classes:
            src = "`names`" if given_names else "ONNX metadata names"
            raise ModelError(f"{src} list {len(known)} classes but model {where} outputs {self.layout.num_classes}")
        self.class_names: tuple[str, ...] = known
        if self.minimal_padding:
            self._check_rectangle(where, hint, known, shapes if freed else None)
        self._allowed = self._parse_classes(classes)
        if preprocessing is None:
            fam = self.family
            if fam == "nms" and _hint_is_yolox(hint):
                fam = "yolox"
            preprocessing = PREPROCESSING[fam]
        self.preprocessing = preprocessing
        self._scale = np.float32(preprocessing.scale)
        self._mean = None if preprocessing.mean is None else np.asarray(preprocessing.mean, np.float32).reshape(3, 1, 1)
        self._inv_std = None if preprocessing.std is None else (1.0 / np.asarray(preprocessing.std, np.float32)).reshape(3, 1, 1)
        self.last_timings_ms: dict[str, float] = {}
        #: Candidate boxes (above ``conf_threshold``) the last :meth:`detect` dropped, by reason: "inverted"
        #: (x1 > x2 or y1 > y2: an export without DFL can predict negative distances) and "non_finite".
        self.last_dropped: dict[str, int] = {"inverted": 0, "non_finite": 0}
        self._warned_inverted = False
        log.debug("loaded %r", self)

    # ------------------------------------------------------------------ helpers
    @staticmethod
    def _parse_size(input_size) -> tuple[int, int] | None:
        if input_size is None:
            return None
        if isinstance(input_size, (int, np.integer)) and not isinstance(input_size, bool):
            input_size = (int(input_size), int(input_size))
        try:
            w, h = input_size
        except (TypeError, ValueError):
            raise ValueError(f"`input_size` must be an int or (width, height), got {input_size!r}") from None
        for v in (w, h):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 32 <= v <= 8192:
                raise ValueError(f"`input_size` must be ints in [32, 8192], got {input_size!r}")
        return int(w), int(h)

    def _metadata_size(self) -> tuple[int, int] | None:
        raw = self.metadata.get("imgsz")
        if not raw:
            return None
        try:
            value = ast.literal_eval(raw.strip())
            if isinstance(value, int):
                value = [value, value]
            h, w = (int(v) for v in value)
        except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError):
            return None
        return (w, h) if w > 0 and h > 0 else None

    def _parse_classes(self, classes) -> np.ndarray | None:
        if classes is None:
            return None
        if isinstance(classes, (str, int)):
            classes = [classes]
        ids = []
        for c in classes:
            if isinstance(c, str):
                if c not in self.class_names:
                    raise ValueError(f"`classes`: unknown class name {c!r}; valid names: {', '.join(self.class_names)}")
                ids.append(self.class_names.index(c))
            elif isinstance(c, (int, np.integer)) and not isinstance(c, bool) and 0 <= c < len(self.class_names):
                ids.append(int(c))
            else:
                raise ValueError(f"`classes` entries must be class names or ids in [0, {len(self.class_names) - 1}], got {c!r}")
        if not ids:
            raise ValueError("`classes` must name at least one class (or be None for all)")
        return np.unique(np.asarray(ids, np.int64))

    def _check_rectangle(self, where: object, hint: str, known: Sequence[str],
                         full: list[tuple[int, ...]] | None) -> None:
        """With ``minimal_padding``: the model must run on a rectangle smaller than ``input_size`` (the height
        halved, rounded up to 32) and give the outputs its family has there (e.g. YOLOX's grid cells), and, an
        export of a fixed size whose size was freed, outputs of another shape than at that size (``full``; every
        family but "nms" predicts per grid cell), else InputSizeError. An export whose graph holds its input size
        (a reshape to a fixed grid) fails here, not later on the first image that is not square."""
        w, h = self.input_size
        probe = (w, max(32, -(-(h // 2) // 32) * 32))
        if probe[1] == h:
            probe = (max(32, -(-(w // 2) // 32) * 32), h)
        import onnxruntime as ort

        quiet = ort.RunOptions()
        quiet.log_severity_level = 4  # the failure is reported here, not logged by onnxruntime as well
        try:
            raw = self.session.run(None, {self.input_name: self._blank_input(probe)}, quiet)
            recognise_layout(self.output_names, [np.shape(r) for r in raw], [np.asarray(r).dtype for r in raw],
                             (probe[1], probe[0]), metadata=self.metadata, hint=hint, family=self.family,
                             num_names=len(known))
            if full is not None and self.family != "nms" and [np.shape(r) for r in raw] == list(full):
                raise InputSizeError(f"the same outputs {list(full)} as at {w}x{h}: the model does not read its "
                                     "input's size")
        except Exception as exc:  # noqa: BLE001 (onnxruntime's classes, ModelError from the layout)
            first = first_line(exc)
            raise InputSizeError(f"`minimal_padding`: model {where} does not run at input sizes other than {w}x{h} "
                                 f"(tried {probe[0]}x{probe[1]}: {first[:300]}); use minimal_padding=False") from None

    def _blank_input(self, size: tuple[int, int] | None = None) -> np.ndarray:
        w, h = size or self.input_size
        shape = (1, 3, h, w) if self.nchw else (1, h, w, 3)
        return np.zeros(shape, dtype=self._input_dtype)

    # ------------------------------------------------------------------ run
    def input_size_for(self, width: int, height: int) -> tuple[int, int]:
        """The model input (width, height) an image of ``width`` x ``height`` is letterboxed into.

        ``input_size``, or with ``minimal_padding`` the smallest multiples of 32 that hold the image resized so
        that it fits ``input_size`` (Ultralytics' ``auto=True`` rectangle).
        """
        if not self.minimal_padding:
            return self.input_size
        in_w, in_h = self.input_size
        r = min(in_w / width, in_h / height)
        nw, nh = min(in_w, max(1, round(width * r))), min(in_h, max(1, round(height * r)))
        return min(in_w, -(-nw // 32) * 32), min(in_h, -(-nh // 32) * 32)

    def preprocess(self, image: np.ndarray) -> tuple[np.ndarray, Letterbox]:
        """Image (BGR uint8 or grey) -> model input tensor and the letterbox for mapping boxes back."""
        img = check_image(image)
        prep = self.preprocessing
        padded, lb = letterbox(img, self.input_size_for(img.shape[1], img.shape[0]), prep)
        if self._input_dtype == np.uint8:
            x = cv2.cvtColor(padded, cv2.COLOR_BGR2RGB) if prep.rgb else padded
            x = x.transpose(2, 0, 1)[None] if self.nchw else x[None]
            return np.ascontiguousarray(x), lb
        blob = cv2.dnn.blobFromImage(padded, scalefactor=float(prep.scale), swapRB=prep.rgb)  # (1, 3, H, W) float32
        if self._mean is not None:
            blob[0] -= self._mean
        if self._inv_std is not None:
            blob[0] *= self._inv_std
        if not self.nchw:
            blob = np.ascontiguousarray(blob.transpose(0, 2, 3, 1))
        if self._input_dtype != np.float32:
            blob = blob.astype(self._input_dtype)
        return blob, lb

    def postprocess(self, outputs: Sequence[np.ndarray], lb: Letterbox, *,
                    input_size: tuple[int, int] | None = None) -> Detections:
        """Raw session outputs -> :class:`Detections` in original-image pixels.

        ``input_size`` (width, height) is the size of the input the outputs came from (default
        ``self.input_size``). Boxes with NaN/inf coordinates or inverted corners (x1 > x2 or y1 > y2) are
        dropped and counted in ``self.last_dropped`` (inverted ones logged, as a warning the first time).
        """
        w, h = input_size or self.input_size
        xyxy, scores, cid = decode(self.layout, outputs, (h, w), self.conf_threshold)
        finite = np.all(np.isfinite(xyxy), axis=1)
        with np.errstate(invalid="ignore"):
            inverted = finite & ((xyxy[:, 2] < xyxy[:, 0]) | (xyxy[:, 3] < xyxy[:, 1]))
        self.last_dropped = {"inverted": int(inverted.sum()), "non_finite": int((~finite).sum())}
        if self.last_dropped["inverted"]:
            (log.debug if self._warned_inverted else log.warning)(
                "%s: dropped %d box(es) with x1 > x2 or y1 > y2 (negative predicted size; exports without DFL "
                "such as YOLO26 can give them)", self.model_path.name if self.model_path else "model",
                self.last_dropped["inverted"])
            self._warned_inverted = True
        ok = finite & ~inverted & np.isfinite(scores) & (cid >= 0) & (cid < len(self.class_names))
        if self._allowed is not None:
            ok &= np.isin(cid, self._allowed)
        if not np.all(ok):
            xyxy, scores, cid = xyxy[ok], scores[ok], cid[ok]
        if scores.size and float(scores.max()) > 1.0 + 1e-3:
            raise ModelError(f"{self.family} decoder got scores up to {float(scores.max()):.4g}, expected probabilities "
                             "in [0, 1]: the export may output logits (no sigmoid) or be of another family; pass family=...")
        scores = np.clip(scores, 0.0, 1.0)
        if scores.size > _MAX_CANDIDATES:
            top = np.argsort(-scores, kind="stable")[:_MAX_CANDIDATES]
            xyxy, scores, cid = xyxy[top], scores[top], cid[top]
        if self.family == "nms":
            keep = np.argsort(-scores, kind="stable")[: self.max_detections]
        else:
            keep = nms(xyxy, scores, cid, iou_threshold=self.iou_threshold, max_detections=self.max_detections)
        boxes = lb.to_original(xyxy[keep])
        visible = (boxes[:, 2] > boxes[:, 0]) & (boxes[:, 3] > boxes[:, 1])
        return Detections(boxes[visible], scores[keep][visible], cid[keep][visible], self.class_names)

    def detect(self, image: np.ndarray) -> Detections:
        """Detect objects in one image.

        Parameters
        ----------
        image : (H, W, 3) uint8 BGR (as ``cv2.imread`` gives), or (H, W) / (H, W, 1) grey uint8

        Returns
        -------
        Detections
            Boxes in pixels of ``image``, clipped to it, highest confidence first. Stage times in
            milliseconds are left in ``self.last_timings_ms`` (``preprocess``, ``inference``,
            ``postprocess``, ``total``).
        """
        t0 = time.perf_counter()
        x, lb = self.preprocess(image)
        t1 = time.perf_counter()
        try:
            raw = self.session.run(None, {self.input_name: x})
        except Exception as exc:  # noqa: BLE001 (onnxruntime's own classes, Fail, InvalidArgument, ...)
            first = first_line(exc)
            where = self.model_path if self.model_path is not None else "<model bytes>"
            raise ModelError(f"model {where} failed on a {x.shape} input: {first[:300]}") from None
        t2 = time.perf_counter()
        dets = self.postprocess(raw, lb, input_size=(int(x.shape[3 if self.nchw else 2]),
                                                     int(x.shape[2 if self.nchw else 1])))
        t3 = time.perf_counter()
        self.last_timings_ms = {"preprocess": (t1 - t0) * 1e3, "inference": (t2 - t1) * 1e3,
                                "postprocess": (t3 - t2) * 1e3, "total": (t3 - t0) * 1e3}
        return dets

    __call__ = detect

    def __repr__(self) -> str:
        src = self.model_path.name if self.model_path else "<bytes>"
        return (f"OnnxDetector({src}: {self.layout.describe()}, input {self.input_size[0]}x{self.input_size[1]}, "
                f"conf>{self.conf_threshold}, iou {self.iou_threshold})")


def _hint_is_yolox(hint: str) -> bool:
    return "yolox" in hint.lower()
