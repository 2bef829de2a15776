"""``python -m benchmarks`` run in-process on one small scene: every file written, every method in the tables."""

from __future__ import annotations

import importlib.util
import json
import re
from pathlib import Path

import numpy as np
import pytest

from benchmarks.__main__ import main
from benchmarks.methods import default_methods
from benchmarks.render import summary_markdown
from benchmarks.scenes import BenchScene, disparity_range, parse_size, speed_inputs
from benchmarks.timing import mde_per_s, time_interleaved

from tests.helpers.onnx_stereo import build_sad_wta  # noqa: E402

FILES = ("report.json", "report.md", "report.html")
HAVE_MPL = importlib.util.find_spec("matplotlib") is not None  # the `bench` extra; CI may not have it


def _check_outputs(out: Path, expected_methods: list[str]) -> dict:
    for name in FILES:
        assert (out / name).is_file() and (out / name).stat().st_size > 0, name
    report = json.loads((out / "report.json").read_text())
    md = (out / "report.md").read_text()
    html = (out / "report.html").read_text()
    assert {"machine", "config", "methods", "scenes", "accuracy", "speed", "memory"} <= set(report)
    machine = report["machine"]
    assert machine["cpu_model"] and machine["logical_cpus"] >= 1 and machine["date_utc"]
    assert all(machine["versions"][k] for k in ("numpy", "numba", "cv2", "onnxruntime"))
    listed = [m["name"] for m in report["methods"]]
    assert listed == expected_methods
    scene_names = list(report["accuracy"])
    assert scene_names, "no scene was evaluated"
    for m in report["methods"]:
        name = m["name"]
        # every method in the methods table, the accuracy tables and the speed tables of md and html
        assert len(re.findall(rf"\| {re.escape(name)} \|", md)) >= 4, name
        assert f"<td>{name}</td>" in html
        if m["available"]:
            for scene in scene_names:
                acc = report["accuracy"][scene][name]
                assert "error" in acc or 0.0 <= acc["full"]["all"]["bad2"] <= 100.0
            rows = [r for r in report["speed"] if r["method"] == name]
            assert rows and all(r.get("median_ms", 1) > 0 for r in rows)
            assert all(len(r["times_ms"]) == report["config"]["repeat"] for r in rows if "times_ms" in r)
    for name in report["figures"].values():
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n"
        assert name in md
    assert html.count("data:image/png;base64,") == len(report["figures"])
    assert "NaN" not in (out / "report.json").read_text()
    return report


def test_cli_on_tsukuba_with_onnx_network(shared_data, tmp_path):
    model = build_sad_wta(tmp_path / "sad_wta.onnx", 16)
    out = tmp_path / "bench"
    code = main(["--data", str(shared_data), "--scenes", "tsukuba", "--repeat", "1", "--quick", "--out", str(out),
                 "--no-progress", "--stereo-onnx", str(model), "--models", str(tmp_path / "no_models")])
    assert code == 0
    expected = [m.name for m in default_methods()] + ["onnx:sad_wta"]
    report = _check_outputs(out, expected)
    assert list(report["accuracy"]) == ["tsukuba"]
    assert set(report["figures"]) == ({"disp:tsukuba", "bad2:Middlebury-style", "speed"} if HAVE_MPL else set())
    assert [s["family"] for s in report["scenes"]] == ["Middlebury-style"]
    assert list(report["accuracy_mean"]) == ["Middlebury-style"]
    # the classical baselines must beat the naive network and StereoBM's density must be the lowest
    acc = report["accuracy"]["tsukuba"]
    assert acc["ocv-hh"]["full"]["all"]["bad2"] < acc["onnx:sad_wta"]["full"]["all"]["bad2"]
    assert acc["ocv-bm"]["full"]["all"]["density"] < acc["ocv-hh"]["full"]["all"]["density"]
    # OpenCV leaves the left band x < num_disparities unknown
    assert acc["ocv-hh"]["border"]["all"]["density"] in (None, 0.0)
    mem = {r["method"]: r for r in report["memory"]}
    assert set(mem) == {m for m in expected if any(x["name"] == m and x["available"] for x in report["methods"])}
    assert all("error" in r or r["peak_rss_mb"] > 0 for r in mem.values())
    assert report["detectors"]["available"] is False  # no models folder given
    summary = summary_markdown(report)
    assert "| sc-default |" in summary and "x vs ocv-hh" in summary and report["machine"]["date_utc"] in summary


def test_cli_on_builtin_demo_without_data(tmp_path, monkeypatch):
    monkeypatch.setattr("benchmarks.scenes.default_data_dir", lambda: None)
    monkeypatch.delenv("STEREO_CLASSIC_DATA", raising=False)
    out = tmp_path / "demo"
    code = main(["--methods", "ocv-bm", "ocv-3way", "--repeat", "2", "--quick", "--out", str(out), "--no-progress",
                 "--no-memory", "--no-objects", "-q"])
    assert code == 0
    report = _check_outputs(out, ["ocv-3way", "ocv-bm"])
    assert len(report["accuracy"]) == 1 and "motorcycle" in next(iter(report["accuracy"])).lower()
    mean = report["accuracy_mean"]["Middlebury-style"]  # the demo is Motorcycle: a Middlebury-style scene
    assert mean["ocv-3way"]["full"]["all"]["bad2"] < mean["ocv-bm"]["full"]["all"]["bad2"]


def test_cli_without_matplotlib_writes_md_and_json(tmp_path, monkeypatch):
    monkeypatch.setattr("benchmarks.render.have_matplotlib", lambda: "ModuleNotFoundError: No module named 'matplotlib'")
    monkeypatch.setattr("benchmarks.scenes.default_data_dir", lambda: None)
    out = tmp_path / "nofig"
    assert main(["--methods", "ocv-bm", "--repeat", "1", "--quick", "--out", str(out), "--no-progress", "--no-memory", "--no-objects", "-q"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["figures"] == {} and not list(out.glob("*.png"))
    assert any("matplotlib" in n for n in report["notes"])
    assert "matplotlib" in (out / "report.md").read_text()


@pytest.mark.parametrize(
    ("argv", "code"),
    [
        (["--repeat", "0"], 2),
        (["--threads", "0,1"], 2),
        (["--sizes", "12x3"], 2),
        (["--methods", "no-such-method", "--quick"], 2),
        (["--onnx-option", "novalue"], 2),
        (["--onnx-option", "colour=rgb"], 2),
        (["--data", "/nonexistent/folder", "--quick"], 1),
    ],
)
def test_cli_bad_arguments(argv, code, tmp_path, capsys):
    assert main(argv + ["--out", str(tmp_path / "x"), "--no-progress"]) == code
    err = capsys.readouterr().err
    assert "error" in err.lower() or "usage" in err.lower()
    assert not (tmp_path / "x" / "report.json").exists()


def test_missing_onnx_model_is_a_runtime_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr("benchmarks.scenes.default_data_dir", lambda: None)
    assert main(["--stereo-onnx", str(tmp_path / "none.onnx"), "--quick", "--out", str(tmp_path / "o"), "--no-progress"]) == 1
    assert "none.onnx" in capsys.readouterr().err


def test_helpers():
    assert parse_size("1242x375x128") == (1242, 375, 128)
    with pytest.raises(ValueError, match="sizes"):
        parse_size("1242x375x100")
    assert mde_per_s(1000, 1000, 100, 1000.0) == pytest.approx(100.0)
    assert mde_per_s(10, 10, 16, None) is None
    calls = []
    res = time_interleaved({"a": lambda: calls.append("a"), "b": lambda: calls.append("b")}, 3)
    assert calls == ["a", "b", "a", "b", "b", "a", "a", "b"]  # first calls, then rotating order
    assert len(res["a"].times_ms) == 3 and res["a"].first_call_ms >= 0
    with pytest.raises(ValueError, match="repeat"):
        time_interleaved({}, 0)
    with pytest.raises(ValueError, match="pause_s"):
        time_interleaved({"a": lambda: None}, 1, pause_s=-1.0)
    slow = time_interleaved({"a": lambda: None}, 2, first_call=False, pause_s=0.05)
    assert max(slow["a"].times_ms) < 50  # the pause is not timed
    gt = np.full((4, 40), np.nan, np.float32)
    gt[0, 0] = 16.0
    scene = BenchScene("s", np.zeros((4, 40, 3), np.uint8), np.zeros((4, 40, 3), np.uint8), gt_disparity=gt)
    assert disparity_range(scene) == 32   # max 16 needs 17 values -> 32
    gt[0, 0] = 15.5
    assert disparity_range(scene) == 16
    inputs = speed_inputs([scene], [(64, 32, 16), (40, 4, 16)])
    assert [i.name for i in inputs] == ["64x32x16"]           # 40x4x16 is the scene itself
    assert inputs[0].left.shape == (32, 64, 3) and "resized" in inputs[0].note


def _no_work(*args, **kwargs):  # pragma: no cover - reaching it is the failure
    raise AssertionError("the command started working before checking its output path")


def test_benchmarks_out_on_an_existing_file_fails_at_once(tmp_path, capsys, monkeypatch):
    import benchmarks.run
    from benchmarks.__main__ import main as bench_main

    monkeypatch.setattr(benchmarks.run, "run_benchmark", _no_work)
    (tmp_path / "report").write_text("x")
    assert bench_main(["--out", str(tmp_path / "report"), "--no-progress"]) == 2
    assert "--out" in capsys.readouterr().err
