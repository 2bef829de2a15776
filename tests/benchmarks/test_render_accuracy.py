"""benchmarks.render_accuracy: family grouping and the three views in every accuracy table."""

from __future__ import annotations

import pytest

from benchmarks.render_accuracy import (
    ACC_HEADERS,
    SUMMARY_HEADERS,
    accuracy_sections,
    bad2_tables,
    summary_tables,
)
from tests.helpers.bench_reports import fake_report


def test_summary_tables_one_per_family_in_order():
    tables = summary_tables(fake_report())
    assert [t.caption.split(":")[0] for t in tables] == ["Middlebury-style", "driving"]
    for t in tables:
        assert t.headers == SUMMARY_HEADERS and [r[0] for r in t.rows] == ["sc-default", "ocv-3way"]


def test_filled_output_dense_equals_ukb_and_valid_reads_measured():
    report = fake_report()
    row = summary_tables(report)[1].rows[0]  # driving, sc-default: filled output, measured subset
    cells = dict(zip(SUMMARY_HEADERS, row))
    assert cells["dense bad-2"] == cells["ukb bad-2"] and cells["density %"] == "100.0"
    assert float(cells["valid density %"]) == pytest.approx(80.0)  # 4 of 20 columns not measured
    theirs = dict(zip(SUMMARY_HEADERS, summary_tables(report)[1].rows[1]))
    assert float(theirs["ukb bad-2"]) > float(theirs["dense bad-2"])  # holes are bad in ukb, filled in dense
    assert theirs["density %"] == theirs["valid density %"]


def test_sections_per_family_and_scene():
    report = fake_report()
    secs = accuracy_sections(report, {"bad2:driving": "bad2_driving.png", "disp:teddy": "disparity_teddy.png"})
    titles = [s.title for s in secs]
    assert titles[:3] == ["Accuracy", "Accuracy: Middlebury-style (1 scene(s))", "Scene teddy"]
    assert titles[3] == "Accuracy: driving (2 scene(s))"
    driving = secs[3]
    assert len(driving.tables) == 4 and driving.tables[0].headers == ACC_HEADERS + ["scenes"]
    assert driving.figures == [("bad2_driving.png", "driving: bad-2 per scene and method in the dense, ukb and valid views")]
    assert all(len(r) == len(ACC_HEADERS) for r in secs[2].tables[0].rows)


def test_bad2_tables_hold_three_views_with_the_family_mean():
    tables = bad2_tables(fake_report())
    assert list(tables) == ["Middlebury-style", "driving"]
    drv = tables["driving"]
    assert list(drv) == ["dense", "all", "valid"]
    assert list(drv["dense"]) == ["16-11-57-101", "16-11-58-603", "mean"]
    a, b = drv["valid"]["16-11-57-101"]["sc-default"], drv["valid"]["16-11-58-603"]["sc-default"]
    assert drv["valid"]["mean"]["sc-default"] == pytest.approx((a + b) / 2)


def test_no_scene_with_ground_truth():
    report = fake_report()
    report["accuracy"] = {}
    assert accuracy_sections(report, {})[0].paragraphs == ["No scene with ground-truth disparity was evaluated."]
