"""benchmarks.run: a method's filled output and measured pixels scored in the right views, family means."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.methods import Method
from benchmarks.run import BenchConfig, family_means, method_metrics, run_benchmark
from benchmarks.scenes import BenchScene


def _scene(family: str = "", source: str = "/data/middlebury2003/fake") -> BenchScene:
    rng = np.random.default_rng(3)
    left = rng.integers(0, 255, (24, 40), dtype=np.uint8)
    gt = np.full((24, 40), 8.0, np.float32)
    return BenchScene("fake", left, left.copy(), gt_disparity=gt, source=source, family=family)


def _filled_method(name: str = "fake-filled") -> Method:
    """Output: the truth except a 4 px error on the first 10 columns, which are 'filled' (not measured)."""

    def factory(setup):
        def run(left, right):
            out = np.full(left.shape, 8.0, np.float32)
            out[:, :10] = 12.0
            measured = out.copy()
            measured[:, :10] = np.nan
            return out, measured

        return run

    return Method(name, "test", "filled output with a measured subset", factory)


def test_method_metrics_scores_output_in_dense_and_ukb_and_measured_in_valid():
    scene = _scene()
    out, measured = _filled_method().prepare(None)(scene.left, scene.right)
    m = method_metrics(out, measured, scene, 16)["full"]
    assert m["dense"]["bad2"] == pytest.approx(25.0) and m["all"]["bad2"] == pytest.approx(25.0)
    assert m["all"]["density"] == pytest.approx(100.0)
    assert m["valid"]["bad2"] == 0.0 and m["valid"]["density"] == pytest.approx(75.0)
    plain = method_metrics(out, out, scene, 16)["full"]  # one array for every view: valid = all here
    assert plain["valid"]["bad2"] == pytest.approx(25.0) and plain["valid"]["density"] == pytest.approx(100.0)


def test_run_benchmark_with_a_fake_filled_method(monkeypatch, tmp_path):
    monkeypatch.setattr("benchmarks.run.default_methods", lambda names=None: [_filled_method()])
    monkeypatch.setattr("benchmarks.run.load_scenes", lambda data_dir, names=None: [_scene()])
    config = BenchConfig(out_dir=tmp_path, repeat=1, quick=True, memory=False, objects=False, figures=False,
                         scaling=False, progress=False, threads=(1,))
    report, arrays = run_benchmark(config)
    assert report["scenes"][0]["family"] == "Middlebury-style"
    acc = report["accuracy"]["fake"]["fake-filled"]["full"]
    assert (acc["dense"]["bad2"], acc["all"]["bad2"], acc["valid"]["bad2"]) == (pytest.approx(25.0), pytest.approx(25.0), 0.0)
    mean = report["accuracy_mean"]["Middlebury-style"]["fake-filled"]
    assert mean["scenes"] == 1 and mean["full"]["valid"]["density"] == pytest.approx(75.0)
    item = arrays["scenes"]["fake"]
    assert np.isfinite(item["outputs"]["fake-filled"]).all() and np.isnan(item["measured"]["fake-filled"][:, :10]).all()
    assert report["scaling"] is None


def test_a_method_returning_a_bad_value_is_reported_not_fatal(monkeypatch, tmp_path):
    bad = Method("bad", "test", "returns a list", lambda setup: (lambda left, right: [1, 2]))
    monkeypatch.setattr("benchmarks.run.default_methods", lambda names=None: [bad, _filled_method()])
    monkeypatch.setattr("benchmarks.run.load_scenes", lambda data_dir, names=None: [_scene()])
    report, _ = run_benchmark(BenchConfig(out_dir=tmp_path, repeat=1, quick=True, memory=False, objects=False,
                                          figures=False, scaling=False, progress=False, threads=(1,)))
    assert "DisparityMap" in report["errors"]["fake"]["bad"]
    assert "error" in report["accuracy"]["fake"]["bad"] and "bad" not in report["accuracy_mean"]["Middlebury-style"]


def test_family_means_never_mix_families():
    acc = {"a": {"m": {"full": {"all": {"bad2": 10.0}}}}, "b": {"m": {"full": {"all": {"bad2": 30.0}}}},
           "c": {"m": {"full": {"all": {"bad2": 50.0}}}, "x": {"error": "failed"}}}
    means = family_means(acc, {"a": "driving", "b": "Middlebury-style", "c": "driving"}, ["m", "x"])
    assert list(means) == ["Middlebury-style", "driving"]
    assert means["driving"]["m"]["full"]["all"]["bad2"] == 30.0 and means["driving"]["m"]["scenes"] == 2
    assert means["Middlebury-style"]["m"]["full"]["all"]["bad2"] == 30.0 and "x" not in means["driving"]


def test_speed_is_timed_on_the_grey_pair_and_accuracy_on_the_pair_as_read(monkeypatch, tmp_path):
    """OpenCV makes its cost from every channel of a colour pair, this matcher from grey: the timed calls of a
    classical method get the grey pair (the same work for all), a network's the pair as read; the scored output
    comes from the first call, on the pair as read."""
    rng = np.random.default_rng(5)
    colour = rng.integers(0, 255, (24, 40, 3), dtype=np.uint8)
    scene = BenchScene("fake", colour, colour.copy(), gt_disparity=np.full((24, 40), 8.0, np.float32),
                       source="/data/middlebury2003/fake", family="")
    seen: dict[str, list[int]] = {}

    def recording(name: str, family: str) -> Method:
        def factory(setup):
            def run(left, right):
                assert left.ndim == right.ndim
                seen.setdefault(name, []).append(left.ndim)
                return np.full(left.shape[:2], 8.0, np.float32)

            return run

        return Method(name, family, "records what it is given", factory)

    methods = [recording("classic", "opencv"), recording("peer", "peer"), recording("net", "onnx")]
    monkeypatch.setattr("benchmarks.run.default_methods", lambda names=None: methods)
    monkeypatch.setattr("benchmarks.run.load_scenes", lambda data_dir, names=None: [scene])
    report, _ = run_benchmark(BenchConfig(out_dir=tmp_path, repeat=2, quick=True, memory=False, objects=False,
                                          figures=False, scaling=False, progress=False, threads=(1,)))
    # first call (scored) on colour, one untimed call on grey (OpenCV's matcher made for colour is made again), 2 timed;
    # a peer (seconds a call) is timed once, without the untimed call
    assert seen["classic"] == [3, 2, 2, 2]
    assert seen["peer"] == [3, 2]
    assert seen["net"] == [3, 3, 3]
    assert report["accuracy"]["fake"]["classic"]["full"]["dense"]["bad2"] == 0.0
