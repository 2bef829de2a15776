"""detectors.imageio.read_image: any path, clear errors (cv2.imread returns None instead)."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from detectors.cli import main
from detectors.imageio import read_image


def _no_imread(*args, **kwargs):  # what cv2.imread does on a non-ASCII path on Windows
    return None


def test_non_ascii_path_reads_without_cv2_imread(tmp_path, monkeypatch):
    img = np.arange(5 * 7 * 3, dtype=np.uint8).reshape(5, 7, 3)
    path = tmp_path / "café_左.png"
    assert cv2.imencode(".png", img)[0]
    path.write_bytes(cv2.imencode(".png", img)[1].tobytes())
    monkeypatch.setattr(cv2, "imread", _no_imread)
    np.testing.assert_array_equal(read_image(path), img)
    assert read_image(str(path), cv2.IMREAD_GRAYSCALE).shape == (5, 7)


def test_errors_name_the_path(tmp_path):
    with pytest.raises(FileNotFoundError, match="missing.png"):
        read_image(tmp_path / "missing.png")
    with pytest.raises(FileNotFoundError, match="image not found"):
        read_image(tmp_path)
    (tmp_path / "bad.png").write_bytes(b"not an image")
    with pytest.raises(ValueError, match="bad.png could not be decoded"):
        read_image(tmp_path / "bad.png")


def test_cli_reads_non_ascii_paths_and_names_unreadable_ones(tmp_path, monkeypatch, yolox_nano, capsys):
    good = tmp_path / "café.png"
    good.write_bytes(cv2.imencode(".png", np.zeros((64, 64, 3), np.uint8))[1].tobytes())
    (tmp_path / "bad.png").write_bytes(b"not an image")
    monkeypatch.setattr(cv2, "imread", _no_imread)
    rc = main(["detect", str(good), str(tmp_path / "bad.png"), "--model", str(yolox_nano), "--threads", "1"])
    assert rc == 1  # one image unreadable
    captured = capsys.readouterr()
    lines = captured.out.strip().splitlines()
    assert len(lines) == 1 and json.loads(lines[0])["image"] == str(good)
    assert "bad.png could not be decoded" in captured.err
