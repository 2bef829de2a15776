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


def test_fetch_of_an_unknown_name_says_how_to_use_a_model_file(capsys):
    """Issue 34: one `error:` line, exit 2, naming the known models and the two ways to use another one."""
    assert main(["fetch", "my_detector"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: no official download for model 'my_detector'")
    assert "--model" in err[0] and "STEREO_CLASSIC_MODELS" in err[0] and "yolox_nano" in err[0]


def test_detect_on_a_missing_image_is_an_error_line(tmp_path, capsys):
    assert main(["detect", str(tmp_path / "nope.png")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and "nope.png" in err[0]


def test_detect_classes_with_commas_or_spaces(tmp_path, monkeypatch):
    from detectors import cli

    seen = []

    class Spy:
        def __init__(self, *args, classes=None, **kwargs):
            seen.append(classes)
            raise ValueError("stop here")

    monkeypatch.setattr("detectors.onnx_detector.OnnxDetector", Spy)
    for classes in (["car,person"], ["car", "person"]):
        assert cli.main(["detect", str(tmp_path / "x.png"), "--classes", *classes]) == 2
    assert seen == [["car", "person"], ["car", "person"]]
