"""benchmarks.render on a fake report: families, three views, thread scaling, pipeline, README block."""

from __future__ import annotations

import json

from benchmarks.render import (
    markdown_sections,
    readme_markdown,
    summary_markdown,
    write_report,
)
from tests.helpers.bench_reports import fake_report


def test_write_report_has_every_section_in_md_and_html(tmp_path):
    report = fake_report()
    written = write_report(report, {}, tmp_path, figures=False)
    assert {p.name for p in written} == {"report.json", "report.md", "report.html"}
    md = (tmp_path / "report.md").read_text()
    html = (tmp_path / "report.html").read_text()
    for title in ("## Accuracy", "### Accuracy: Middlebury-style (1 scene(s))", "### Accuracy: driving (2 scene(s))",
                  "## Thread scaling", "## Whole pipeline", "## Per-object distance against KITTI labels"):
        assert title in md, title
    assert md.index("Middlebury-style (1 scene") < md.index("driving (2 scene")  # FAMILIES order
    # the three views explained, and that the matcher's valid view reads measured pixels only
    assert "**dense**" in md and "**ukb**" in md and "filled_disparity" in md and "fill_holes" in md
    # per-scene bad-2 tables exist for each view; driving scenes under their short names
    for view in ("dense", "ukb", "valid"):
        assert f"driving: bad-2 % per scene, view {view}" in md
    assert "| method | 16-11-57-101 | 16-11-58-603 | mean |" in md
    # thread scaling: one row per method and thread count, identity stated
    assert md.count("| sc-default | 8 |") == 1 and "| ocv-3way | 8 |" in md and "| NO |" in md
    assert "<h2>Thread scaling</h2>" in html and "fake: no KITTI labels" in md
    assert json.loads((tmp_path / "report.json").read_text())["schema"] == "stereo_classic.benchmarks/2"


def test_summary_has_one_accuracy_table_per_family_with_three_views():
    md = summary_markdown(fake_report())
    assert md.count("| method | dense bad-2 | dense D1 | ukb bad-2 | ukb D1 | valid bad-2 | valid D1 | density % | "
                    "valid density % |") == 2
    assert "*Middlebury-style: bad-2 and D1 %, mean over 1 scene(s) (teddy)*" in md
    assert "frames/s, detector concurrent" in md and "| kitti_object_pair | 1242x375x128 | 15.0 | 17.5 |" in md


def test_readme_block_numbers_come_from_the_report():
    report = fake_report()
    text = readme_markdown(report)
    mean = report["accuracy_mean"]["driving"]["sc-default"]["full"]
    row = next(line for line in text.splitlines() if line.startswith("| driving (2) | sc-default |"))
    assert row == (f"| driving (2) | sc-default | {mean['dense']['bad2']:.2f} | {mean['all']['bad2']:.2f} | "
                   f"{mean['valid']['bad2']:.2f} | {mean['valid']['density']:.1f} |")
    assert "**Speed** at 1242x375x128, grey pair, 2 thread(s), median: `sc-default` 40.0 ms; `ocv-3way` 50.0 ms (1.25x)" in text
    assert "at 640x480x64" not in text  # no VGA rows in this report: no VGA line
    vga = [dict(r, input="640x480x64", kind="synthetic", width=640, height=480, num_disparities=64,
                median_ms=r["median_ms"] / 4) for r in report["speed"]]
    text = readme_markdown({**report, "speed": report["speed"] + vga})
    assert "**Speed** at 640x480x64, grey pair, 2 thread(s), median: `sc-default` 10.0 ms; `ocv-3way` 12.5 ms (1.25x)" in text
    assert ("threads 1 / 2 / 4 / 8: `sc-default` 80.0 / 40.0 / 40.0 / 40.0 ms (speed-up 1.00 / 2.00 / 2.00 / 2.00; "
            "fastest calls 1.00 / 1.41 / 1.41 / 1.41)") in text
    assert "bit-identical at every thread count: yes" in text
    assert "1242x375x128 15.0 frames/s; 640x480x64 30.0 frames/s" in text  # not the concurrent row
    assert report["command"][-1] in text


def test_markdown_sections_keep_the_order_of_tables_and_notes():
    secs = markdown_sections("T", "intro\n\n| a | b |\n|---|---|\n| 1 | 2 |\n\n- note one\n- note two\n")
    assert [s.title for s in secs] == ["T", "T: notes"]
    assert secs[0].paragraphs == ["intro"] and secs[0].tables[0].headers == ["a", "b"]
    assert secs[0].tables[0].rows == [["1", "2"]] and secs[1].paragraphs == ["- note one", "- note two"]
