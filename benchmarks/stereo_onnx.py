"""Run a learned ONNX stereo network on the benchmark's pairs, so it can be checked against the classical baseline.

The model takes the left and right image and returns a disparity map. What the network expects is
read from the model's metadata (``metadata_props``) and can be overridden by options:

=================  ==========================================================  ====================
key                meaning                                                     default
=================  ==========================================================  ====================
``input_size``     ``WIDTHxHEIGHT`` the pair is resized to                     the model's static
                                                                               input shape, else
                                                                               the image size
``color``          ``rgb``, ``bgr`` or ``gray``                                ``rgb`` (3 channels)
``pixel_scale``    factor applied to 0-255 pixel values first                  ``1/255``
``mean``, ``std``  per-channel, after ``pixel_scale``: ``(x - mean) / std``     0 and 1
``output_scale``   factor from the raw output to disparity in input pixels     1
``pad_multiple``   for dynamic sizes: pad right/bottom to a multiple of this   1
=================  ==========================================================  ====================

Inputs are the graph inputs named ``left`` and ``right`` (else the first two), NCHW; the output is
the one named ``disparity`` (else the first), any of (1, 1, H, W), (1, H, W) or (H, W). When the
network ran at another width than the image, the disparity is resized back and multiplied by the
width ratio. Values that are not finite or below ``min_disparity`` become NaN.

Usage (needs files that are not part of the package)::

    stereo = OnnxStereo("model.onnx", input_size=(640, 384))
    disparity = stereo.compute(left_bgr, right_bgr)
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

__all__ = ["OnnxStereoError", "OnnxStereoConfig", "OnnxStereo", "onnx_method", "parse_options"]


class OnnxStereoError(ValueError):
    """A stereo model that cannot be used as given (not ONNX, unexpected inputs or outputs, bad options)."""


_COLORS = ("rgb", "bgr", "gray")


@dataclass(frozen=True)
class OnnxStereoConfig:
    """Pre- and post-processing of one ONNX stereo network (see the module docstring)."""

    input_size: tuple[int, int] | None = None
    color: str = "rgb"
    pixel_scale: float = 1.0 / 255.0
    mean: tuple[float, ...] = (0.0,)
    std: tuple[float, ...] = (1.0,)
    output_scale: float = 1.0
    pad_multiple: int = 1

    def __post_init__(self) -> None:
        if self.input_size is not None:
            if len(self.input_size) != 2 or any(int(v) != v or v < 1 for v in self.input_size):
                raise OnnxStereoError(f"`input_size` must be (width, height) positive integers, got {self.input_size!r}")
        if self.color not in _COLORS:
            raise OnnxStereoError(f"`color` must be one of {_COLORS}, got {self.color!r}")
        for name in ("pixel_scale", "output_scale"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value != 0):
                raise OnnxStereoError(f"`{name}` must be a finite non-zero number, got {value!r}")
        for name in ("mean", "std"):
            value = getattr(self, name)
            if not value or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in value):
                raise OnnxStereoError(f"`{name}` must be one or more finite numbers, got {value!r}")
        if any(v == 0 for v in self.std):
            raise OnnxStereoError(f"`std` must not contain 0, got {self.std!r}")
        if not isinstance(self.pad_multiple, int) or self.pad_multiple < 1:
            raise OnnxStereoError(f"`pad_multiple` must be an integer >= 1, got {self.pad_multiple!r}")


def _floats(key: str, text: str) -> tuple[float, ...]:
    try:
        return tuple(float(v) for v in str(text).replace(" ", "").strip("()[]").split(",") if v)
    except ValueError:
        raise OnnxStereoError(f"`{key}` must be comma-separated numbers, got {text!r}") from None


def parse_options(values: Mapping[str, Any]) -> dict[str, Any]:
    """Turn string options (metadata props or ``KEY=VALUE`` on the command line) into config fields."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        key = key.strip().lower()
        if key in ("input_size", "size"):
            if isinstance(value, str):
                parts = value.lower().replace(",", "x").split("x")
                try:
                    w, h = (int(p) for p in parts)
                except ValueError:
                    raise OnnxStereoError(f"`input_size` must look like WIDTHxHEIGHT, got {value!r}") from None
                out["input_size"] = (w, h)
            elif value is not None:
                out["input_size"] = tuple(int(v) for v in value)
        elif key == "color":
            out["color"] = str(value).strip().lower()
        elif key in ("pixel_scale", "scale", "output_scale"):
            key = "pixel_scale" if key == "scale" else key
            try:
                out[key] = float(value)
            except ValueError:
                raise OnnxStereoError(f"`{key}` must be a number, got {value!r}") from None
        elif key in ("mean", "std"):
            out[key] = _floats(key, value) if isinstance(value, str) else tuple(float(v) for v in value)
        elif key == "pad_multiple":
            try:
                out[key] = int(value)
            except ValueError:
                raise OnnxStereoError(f"`pad_multiple` must be an integer, got {value!r}") from None
        # other metadata keys (author, licence, ...) are ignored
    return out


class OnnxStereo:
    """An ONNX stereo network run with onnxruntime.

    Parameters
    ----------
    model : str or Path
        The ``.onnx`` file.
    threads : int, optional
        onnxruntime intra-op threads (None: onnxruntime's default).
    providers : sequence of str
    **options
        Config fields overriding the model's metadata: ``input_size=(w, h)`` or ``"WxH"``,
        ``color``, ``pixel_scale``, ``mean``, ``std``, ``output_scale``, ``pad_multiple``.

    Raises
    ------
    FileNotFoundError
        ``model`` does not exist.
    OnnxStereoError
        Not an ONNX model, fewer than two image inputs, or bad options.
    """

    def __init__(self, model: str | Path, *, threads: int | None = None, providers: Sequence[str] = ("CPUExecutionProvider",), **options: Any) -> None:
        import onnxruntime as ort

        path = Path(model)
        if not path.is_file():
            raise FileNotFoundError(f"`model` must be an ONNX stereo model file, got {str(path)!r} which does not exist")
        so = ort.SessionOptions()
        if threads is not None:
            so.intra_op_num_threads = int(threads)
            so.inter_op_num_threads = 1
        so.log_severity_level = 3
        try:
            self.session = ort.InferenceSession(str(path), sess_options=so, providers=list(providers))
        except Exception as exc:  # noqa: BLE001 - onnxruntime raises its own classes for bad files
            raise OnnxStereoError(f"`model` {str(path)!r} could not be loaded as an ONNX model: {exc}") from None
        self.path = path
        inputs = self.session.get_inputs()
        if len(inputs) < 2:
            raise OnnxStereoError(f"`model` {path.name} must take two image inputs (left, right), it has {len(inputs)}: {[i.name for i in inputs]}")
        by_name = {i.name.lower(): i for i in inputs}
        self._left = by_name.get("left", inputs[0])
        self._right = by_name.get("right", inputs[1] if inputs[1] is not by_name.get("left") else inputs[0])
        for inp in (self._left, self._right):
            if len(inp.shape) != 4:
                raise OnnxStereoError(f"`model` input {inp.name!r} must be NCHW (4-D), got shape {inp.shape}")
            if inp.type not in ("tensor(float)", "tensor(uint8)", "tensor(float16)"):
                raise OnnxStereoError(f"`model` input {inp.name!r} must be float or uint8, got {inp.type}")
        outputs = self.session.get_outputs()
        self._output = next((o for o in outputs if o.name.lower() == "disparity"), outputs[0])
        meta = dict(self.session.get_modelmeta().custom_metadata_map or {})
        self.metadata = meta
        fields = parse_options(meta)
        fields.update(parse_options(options))
        channels = self._left.shape[1]
        if "color" not in fields and channels == 1:
            fields["color"] = "gray"
        static = [d for d in self._left.shape[2:] if isinstance(d, int)]
        if "input_size" not in fields and len(static) == 2:
            fields["input_size"] = (int(self._left.shape[3]), int(self._left.shape[2]))
        self.config = OnnxStereoConfig(**fields)
        want_c = 1 if self.config.color == "gray" else 3
        if isinstance(channels, int) and channels != want_c:
            raise OnnxStereoError(f"`color` {self.config.color!r} gives {want_c} channels but the model input {self._left.name!r} has {channels}")

    def _prepare(self, image: np.ndarray, size: tuple[int, int], pad: tuple[int, int]) -> np.ndarray:
        cfg = self.config
        img = image
        if img.ndim == 3 and img.shape[2] == 1:
            img = img[:, :, 0]
        if cfg.color == "gray":
            img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img
        elif img.ndim == 2:
            img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
        if cfg.color == "rgb":
            img = img[:, :, ::-1]
        if (img.shape[1], img.shape[0]) != size:
            img = cv2.resize(np.ascontiguousarray(img), size, interpolation=cv2.INTER_LINEAR)
        if pad != (0, 0):
            widths = ((0, pad[1]), (0, pad[0])) + (((0, 0),) if img.ndim == 3 else ())
            img = np.pad(img, widths, mode="edge")
        chw = img[None, None] if img.ndim == 2 else np.transpose(img, (2, 0, 1))[None]
        if self._left.type == "tensor(uint8)":
            return np.ascontiguousarray(chw.astype(np.uint8))
        x = chw.astype(np.float32) * np.float32(cfg.pixel_scale)
        n = x.shape[1]
        mean = np.asarray(cfg.mean if len(cfg.mean) == n else cfg.mean[:1] * n, np.float32).reshape(1, n, 1, 1)
        std = np.asarray(cfg.std if len(cfg.std) == n else cfg.std[:1] * n, np.float32).reshape(1, n, 1, 1)
        x = (x - mean) / std
        if self._left.type == "tensor(float16)":
            x = x.astype(np.float16)
        return np.ascontiguousarray(x)

    def compute(self, left: np.ndarray, right: np.ndarray, *, min_disparity: float = 0.0) -> np.ndarray:
        """Disparity of the pair.

        Parameters
        ----------
        left, right : (H, W, 3) BGR or (H, W) grey uint8 arrays of the same shape
        min_disparity : float
            Values below this become NaN.

        Returns
        -------
        (H, W) float32, pixels of the input image, NaN unknown
        """
        left = np.asarray(left)
        right = np.asarray(right)
        if left.shape != right.shape or left.ndim not in (2, 3) or left.size == 0:
            raise ValueError(f"`left` and `right` must be non-empty images of the same shape, got {left.shape} and {right.shape}")
        if left.dtype != np.uint8 or right.dtype != np.uint8:
            raise ValueError(f"`left` and `right` must be uint8 images, got {left.dtype} and {right.dtype}")
        h, w = left.shape[:2]
        size = self.config.input_size or (w, h)
        m = self.config.pad_multiple
        pad = ((-size[0]) % m, (-size[1]) % m) if self.config.input_size is None else (0, 0)
        feeds = {self._left.name: self._prepare(left, size, pad), self._right.name: self._prepare(right, size, pad)}
        raw = self.session.run([self._output.name], feeds)[0]
        out = np.asarray(raw, dtype=np.float32)
        while out.ndim > 2 and out.shape[0] == 1:
            out = out[0]
        if out.ndim != 2:
            raise OnnxStereoError(f"`model` output {self._output.name!r} must be a single disparity map, got shape {np.shape(raw)}")
        if pad != (0, 0) and out.shape == (size[1] + pad[1], size[0] + pad[0]):
            out = out[: size[1], : size[0]]
        net_w = out.shape[1]
        disp = out * np.float32(self.config.output_scale)
        if disp.shape != (h, w):
            disp = cv2.resize(disp, (w, h), interpolation=cv2.INTER_LINEAR) * np.float32(w / net_w)
        disp = disp.astype(np.float32, copy=False)
        disp[~np.isfinite(disp) | (disp < min_disparity)] = np.nan
        return disp


def onnx_method(path: str | Path, *, name: str | None = None, **options: Any) -> Any:
    """A :class:`benchmarks.methods.Method` running the ONNX stereo network at ``path``.

    The model is opened once here (so a bad file fails early, with its reason) and once per thread
    count when the benchmark prepares it.
    """
    from benchmarks.methods import Method

    path = Path(path)
    probe = OnnxStereo(path, **options)
    label = name or f"onnx:{path.stem}"
    params = {"path": str(path), **{k: (list(v) if isinstance(v, tuple) else v) for k, v in vars(probe.config).items()}}

    def factory(setup: Any) -> Any:
        stereo = OnnxStereo(path, threads=setup.threads, **options)

        def run(left: np.ndarray, right: np.ndarray) -> np.ndarray:
            return stereo.compute(left, right, min_disparity=setup.min_disparity)

        return run

    cfg = probe.config
    desc = f"ONNX stereo network {path.name} (input {cfg.input_size or 'image size'}, {cfg.color}, output x{cfg.output_scale:g})"
    return Method(label, "onnx", desc, factory, params=params)

