"""Error classes of the detectors package."""

from __future__ import annotations

__all__ = ["InputSizeError", "ModelError", "ModelNotFoundError", "first_line"]


class ModelError(ValueError):
    """A model file that cannot be used: not ONNX, corrupt, unknown input/output layout, bad checksum."""


class ModelNotFoundError(FileNotFoundError):
    """No model file where one was looked for; the message is one line saying where to put it."""


class InputSizeError(ModelError):
    """A model that does not run at the input size asked of it (``OnnxDetector(minimal_padding=True)`` on an export
    whose graph holds its input size, e.g. a reshape to a fixed grid)."""


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message (onnxruntime's run to pages), or its class name when it has none."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__
