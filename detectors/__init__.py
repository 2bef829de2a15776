"""detectors: exported ONNX object detectors run with onnxruntime."""

__all__: list[str] = []
