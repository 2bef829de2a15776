"""``python -m detectors detect``: a model that fails on the images is one `error:` line and exit code 1, not a
traceback (issue #15 item 10); ``-v`` adds the traceback."""

from __future__ import annotations

import cv2
import numpy as np

from detectors.cli import main
from tests.helpers.onnx_detectors import constant_detector


def _logits_model(path):
    raw = np.zeros((1, 84, 500), np.float32)
    raw[0, :4, 0] = (100, 100, 40, 40)
    raw[0, 4, 0] = 7.5  # a logit, not a probability: the decoder refuses it in detect()
    path.write_bytes(constant_detector({"output0": raw}))
    return path


def test_model_error_in_detect_is_one_line_and_exit_1(tmp_path, capsys):
    model = _logits_model(tmp_path / "logits.onnx")
    images = []
    for name in ("a.png", "b.png"):
        cv2.imwrite(str(tmp_path / name), np.zeros((40, 60, 3), np.uint8))
        images.append(str(tmp_path / name))
    assert main(["detect", *images, "--model", str(model)]) == 1
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err
    assert "error:" in captured.err and "expected probabilities" in captured.err
    assert captured.err.count("expected probabilities") == 1  # stops at the first image: the rest fail alike
    assert captured.out == ""


def test_model_error_traceback_with_verbose(tmp_path, capsys):
    model = _logits_model(tmp_path / "logits.onnx")
    cv2.imwrite(str(tmp_path / "a.png"), np.zeros((40, 60, 3), np.uint8))
    assert main(["-v", "detect", str(tmp_path / "a.png"), "--model", str(model)]) == 1
    assert "Traceback" in capsys.readouterr().err
