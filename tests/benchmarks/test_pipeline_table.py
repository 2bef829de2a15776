"""benchmarks.pipeline_table: run and guide frame by frame, and its place in the report and the README block."""

from __future__ import annotations

from benchmarks import pipeline_table
from benchmarks.render import readme_markdown, write_report
from tests.helpers.bench_reports import fake_report


def _row(command: str, stages: dict[str, float]) -> dict:
    return {"available": True, "command": command, "input": "KITTI pair x30", "size": [1242, 375],
            "num_disparities": 128, "frames": 30, "fps": 1000.0 / stages["total"],
            "latency_median_ms": stages["total"], "model": "yolox_nano.onnx",
            "stages": {k: {"median_ms": v, "cpu_ms": 2 * v} for k, v in stages.items()}}


TABLE = {"available": True, "how": "fake", "rows": [
    _row("run", {"read": 4.0, "disparity": 40.0, "checks": 1.5, "write": 0.1, "total": 50.0}),
    _row("guide", {"read": 4.0, "disparity": 40.0, "checks": 1.5, "guide": 8.0, "write": 0.1, "total": 58.0}),
    {"available": False, "command": "run", "input": "OAK-D 12 scenes", "reason": "FileNotFoundError: x"}]}


def test_the_table_has_a_column_per_command_and_input_and_says_what_is_missing():
    text = pipeline_table.format_table(TABLE)
    lines = text.splitlines()
    assert lines[0] == ("| stage: median ms / CPU ms per frame | `run` KITTI pair x30 (1242x375x128) | `guide` KITTI "
                        "pair x30 (1242x375x128) |")
    assert "| checks | 1.5 / 3.0 | 1.5 / 3.0 |" in lines
    assert "| guide | - | 8.0 / 16.0 |" in lines             # run has no guide stage
    assert "| frames/s | 20.0 | 17.2 |" in lines
    assert "| latency, read to record written (median ms) | 50 | 58 |" in lines
    assert "run OAK-D 12 scenes: FileNotFoundError: x" in text
    order = [line.split(" | ")[0][2:] for line in lines[2:-4]]
    assert order == ["read", "disparity", "checks", "guide", "write", "total"]


def test_not_measured_says_why():
    assert "no yolox_nano" in pipeline_table.format_table(pipeline_table.measure(None, None))
    assert pipeline_table.measure(None, __file__)["available"] is False  # no data folder


def test_report_and_readme_block_carry_the_table(tmp_path):
    report = fake_report()
    write_report(report, {}, tmp_path / "a", figures=False)
    md = (tmp_path / "a" / "report.md").read_text()
    assert "## Pipeline stages of run and guide" in md and "not measured in this run" in md
    assert "frame by frame" not in readme_markdown(report)
    report["pipeline_table"] = TABLE
    write_report(report, {}, tmp_path / "b", figures=False)
    assert "| checks | 1.5 / 3.0 | 1.5 / 3.0 |" in (tmp_path / "b" / "report.md").read_text()
    assert "| checks | 1.5 / 3.0 | 1.5 / 3.0 |" in readme_markdown(report)


def test_measured_on_the_shared_scenes(shared_data, yolox_nano, monkeypatch):
    """Every row; and every Localizer is warmed up as ``run`` does it, with the frame checks' kernels loaded before
    its first frame (with a cold numba cache a look's kernels were compiled inside a timed frame)."""
    import stereo_classic.pipeline as pipeline

    loaded = []
    real = pipeline.load_frame_kernels
    monkeypatch.setattr(pipeline, "load_frame_kernels", lambda params: (loaded.append(params), real(params))[1])
    table = pipeline_table.measure(shared_data, yolox_nano, frames=2)
    assert [(p.num_disparities, p.threads) for p in loaded] == [(128, 2)] * 4 + [(64, 2)] * 4  # 2 loops a row
    rows = table["rows"]
    assert [(r["command"], r["input"]) for r in rows] == [
        ("run", "KITTI pair x30"), ("guide", "KITTI pair x30"), ("run", "OAK-D 12 scenes"), ("guide", "OAK-D 12 scenes")]
    for r in rows:
        assert r["available"] and r["frames"] == 2 and r["fps"] > 0 and r["latency_median_ms"] > 0
        assert {"read", "disparity", "detect", "localize", "checks", "write", "total"} <= set(r["stages"])
        assert ("guide" in r["stages"]) == (r["command"] == "guide")
        assert all(v["median_ms"] >= 0 and v["cpu_ms"] >= 0 for v in r["stages"].values())
