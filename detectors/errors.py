"""Error classes of the detectors package."""

from __future__ import annotations

__all__ = ["ModelError", "ModelNotFoundError"]


class ModelError(ValueError):
    """A model file that cannot be used: not ONNX, corrupt, unknown input/output layout, bad checksum."""


class ModelNotFoundError(FileNotFoundError):
    """No model file where one was looked for; the message is one line saying where to put it."""
