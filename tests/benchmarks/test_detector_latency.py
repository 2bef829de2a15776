"""benchmarks.detector_latency: per-stage latency of a detector, thread counts interleaved."""

from __future__ import annotations

import pytest

from benchmarks.detector_latency import format_table, measure_latency
from detectors.imageio import read_image


def test_measure_latency_rows(yolox_nano, shared_data):
    path = shared_data / "oakd/selfie_left.png"
    if not path.is_file():
        pytest.skip(f"{path} not present")
    image = read_image(path)
    rows = measure_latency(yolox_nano, [image], threads=(1, 2), repeats=2, warmup=1)
    assert [r["threads"] for r in rows] == [1, 2]
    for r in rows:
        assert r["family"] == "yolox" and r["n"] == 2
        assert r["inference_ms"] > 0 and r["total_ms"] >= r["inference_ms"]
    assert "yolox_nano.onnx" in format_table(rows)
    with pytest.raises(ValueError, match="`repeats`"):
        measure_latency(yolox_nano, [image], repeats=0)
    with pytest.raises(ValueError, match="`images`"):
        measure_latency(yolox_nano, [])
