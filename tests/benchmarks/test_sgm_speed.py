"""benchmarks.sgm_speed: the thread counts and the thread-scaling table on a tiny pair."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.sgm_speed import (
    format_scaling,
    scaling_threads,
    thread_scaling,
    usable_cores,
)


def test_scaling_threads_cover_the_cores_and_oversubscription():
    assert scaling_threads(1) == (1, 2, 4, 8)
    assert scaling_threads(2) == (1, 2, 4, 8)
    assert scaling_threads(12) == tuple(range(1, 13))
    assert scaling_threads()[-1] >= usable_cores() >= 1


def test_thread_scaling_table_on_a_tiny_pair():
    rng = np.random.default_rng(1)
    left = rng.integers(0, 255, (24, 48), dtype=np.uint8)
    right = np.roll(left, -3, axis=1)
    res = thread_scaling(left, right, num_disparities=16, threads=(2, 3), repeat=1, name="tiny", pause_s=0.0)
    assert res["threads"] == [1, 2, 3] and res["methods"] == ["sc-default", "ocv-3way"]
    assert [(r["method"], r["threads"]) for r in res["rows"]] == [
        ("sc-default", 1), ("ocv-3way", 1), ("sc-default", 2), ("ocv-3way", 2), ("sc-default", 3), ("ocv-3way", 3)]
    for r in res["rows"]:
        assert r["median_ms"] > 0 and r["cpu_s_per_call"] >= 0 and isinstance(r["identical"], bool)
        assert r["efficiency"] == pytest.approx(r["speedup"] / min(r["threads"], res["cores"]))
    firsts = [r for r in res["rows"] if r["threads"] == 1]
    assert all(r["speedup"] == 1.0 and r["speedup_best"] == 1.0 and r["identical"] for r in firsts)
    one = {r["method"]: r for r in firsts}
    for r in res["rows"]:
        assert r["speedup_best"] == pytest.approx(one[r["method"]]["min_ms"] / r["min_ms"])
    assert "tiny" == res["input"] and "identical" in format_scaling(res)


def test_thread_scaling_rejects_bad_arguments():
    img = np.zeros((8, 8), np.uint8)
    with pytest.raises(ValueError, match="`repeat` must be an integer >= 1"):
        thread_scaling(img, img, repeat=0)
    with pytest.raises(ValueError, match="`threads` must be integers >= 1"):
        thread_scaling(img, img, threads=(0, 2))


def test_thread_scaling_times_the_grey_pair(monkeypatch):
    """OpenCV makes its cost from every channel of a colour pair, the matcher from grey: the scaling table gives
    every method the grey pair (benchmarks.methods.timing_pair), first call included."""
    from benchmarks.methods import Method

    seen: list[int] = []

    def factory(setup):
        def run(left, right):
            seen.append(left.ndim)
            return np.zeros(left.shape[:2], np.float32)

        return run

    monkeypatch.setattr("benchmarks.methods.default_methods",
                        lambda names=None: [Method("rec", "opencv", "records what it is given", factory)])
    colour = np.random.default_rng(2).integers(0, 255, (16, 32, 3), dtype=np.uint8)
    res = thread_scaling(colour, colour.copy(), num_disparities=16, threads=(1,), repeat=2, methods=("rec",),
                         pause_s=0.0)
    assert seen and set(seen) == {2} and res["rows"][0]["identical"]
