"""benchmarks.density: per-step removal counts, the filter bound, and the command on synthetic and real scenes."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks import density
from benchmarks.scenes import BenchScene
from tests.helpers.scenes import planted_scene


@pytest.fixture(scope="module")
def planted() -> BenchScene:
    # a box at d = 42 in front of a wall at d = 10.5 (range 48): a 31.5 px wall strip left of the box is hidden in
    # the right view
    left, right, gt, _ = planted_scene(width=240, height=120, z_wall=8.0, z_box=2.0, box=(90, 30, 170, 90), seed=3)
    return BenchScene(name="planted", left=left, right=right, gt_disparity=gt, source="synthetic")


@pytest.mark.parametrize("raw_bad, raw_density, density_, want", [
    (30.0, 100.0, 80.0, 12.5),   # 30 bad of 100; removing 20, all bad, leaves 10 of 80
    (30.0, 100.0, 100.0, 30.0),  # nothing removed
    (10.0, 100.0, 50.0, 0.0),    # more removed than there are bad pixels
    (20.0, 90.0, 90.0, 20.0),    # raw density below 100: the same rule on what exists
])
def test_bad2_floor_values(raw_bad, raw_density, density_, want):
    assert density.bad2_floor(raw_bad, raw_density, density_) == pytest.approx(want)


@pytest.mark.parametrize("density_", [0.0, -1.0, 100.5])
def test_bad2_floor_rejects_a_density_outside_the_raw_one(density_):
    with pytest.raises(ValueError, match="density"):
        density.bad2_floor(10.0, 100.0, density_)


def test_step_rows_counts_each_step_on_ground_truth_pixels_only():
    gt = np.array([[1.0, 1.0, 1.0, 1.0, np.nan]], np.float32)
    raw = np.array([[1.0, 9.0, 1.5, 9.0, 9.0]], np.float32)   # two bad winners where there is ground truth
    f, t = False, True
    removed = {"lr+uniqueness": np.array([[f, t, f, f, t]]),  # one bad removed (the other has no GT)
               "border": np.array([[f, f, t, f, f]]),         # one right removed
               "speckle": np.zeros((1, 5), bool)}
    kept = np.array([[t, f, f, t, f]])
    row = density.step_rows(raw, removed, kept, gt)
    assert row["raw_density"] == 100.0 and row["raw_bad2"] == 50.0
    assert row["lr+uniqueness_removed"] == 25.0 and row["lr+uniqueness_bad2"] == 100.0
    assert row["border_removed"] == 25.0 and row["border_bad2"] == 0.0
    assert row["speckle_removed"] == 0.0 and np.isnan(row["speckle_bad2"])
    assert row["density"] == 50.0 and row["bad2"] == 50.0
    # x=0 (d=1) lands outside the right image: only the left view sees it, and it is measured (right)
    assert row["visible"] == 75.0 and row["hidden_measured"] == 25.0 and row["hidden_bad2"] == 0.0
    # the output fills the three holes from the background (1.0) and only the kept bad winner stays wrong
    assert row["dense_bad2"] == 25.0
    # left unknown, the dense view fills them as the KITTI devkit does (the smaller neighbour, here 1.0 too)
    assert density.step_rows(raw, removed, kept, gt, fill_holes=False)["dense_bad2"] == 25.0


def test_removal_masks_partition_the_winners_and_the_lr_step_removes_the_occlusion(planted):
    raw, removed, kept = density.removal_masks(planted)
    assert raw.shape == kept.shape == planted.gt_disparity.shape and raw.dtype == np.float32
    masks = [removed[s] for s in density.STEPS] + [kept]
    assert sum(m.astype(int) for m in masks).max() == 1                       # disjoint
    assert np.array_equal(np.logical_or.reduce(masks), np.isfinite(raw))      # and cover every winner
    row = density.step_rows(raw, removed, kept, planted.gt_disparity)
    # the wall strip hidden by the box (31.5 px x 60 rows = 6.6 % of the image) is what the LR check must remove
    # (measured: 10.5 %, 77 % of them wrong), and what is kept is nearly all right (measured 0.2 % bad, raw 9 %)
    assert row["lr+uniqueness_removed"] > 4.0 and row["lr+uniqueness_bad2"] > 50.0
    assert row["bad2"] < 2.0 < row["raw_bad2"]
    assert row["border_removed"] > 0.0                                        # the left band x < 24 (half of the 48 disparities)


def test_removal_masks_follow_the_settings(planted):
    _, removed, kept = density.removal_masks(planted, border_reach=0.0, speckle_size=0)
    assert not removed["border"].any() and not removed["speckle"].any()
    _, removed_off, _ = density.removal_masks(planted, lr_check=None)
    assert not removed_off["lr+uniqueness"].any()


def test_family_table_lines():
    rows = [{"raw_density": 100.0, "raw_bad2": 30.0, "density": 70.0, "bad2": 5.0, "dense_bad2": 9.0,
             "visible": 90.0, "hidden_measured": 2.0, "hidden_bad2": 40.0,
             **{f"{s}_removed": 10.0 for s in density.STEPS}, **{f"{s}_bad2": 80.0 for s in density.STEPS}}]
    lines = density.family_table(rows, target_density=80.0)
    assert lines[0].startswith("| step |") and len(lines) == 2 + 1 + len(density.STEPS) + 4 + 1
    assert "| lr+uniqueness | 10.00 | 80.0 |" in lines and "| output (dense view) | | dense bad-2 9.00 |" in lines
    assert "| of them seen by the left view only (no correspondence) | 2.00 | 40.0 |" in lines
    assert "| ground truth seen by both views (the most matching can measure) | density 90.0 | |" in lines
    assert lines[-1].endswith(">= 12.50 |")


@pytest.mark.parametrize("argv", [["--data", "/nonexistent/folder"], ["--set", "not_a_field=1"],
                                  ["--set", "p1=-5"], ["--threads", "0"]])
def test_main_error_paths(argv):
    assert density.main(argv) == 2


def test_main_on_a_real_scene(shared_data, capsys):
    assert density.main(["--data", str(shared_data), "--scenes", "tsukuba", "--target", "Middlebury-style=95"]) == 0
    out = capsys.readouterr().out
    assert "*Middlebury-style: mean over 1 scene(s), matcher defaults" in out
    assert "| lr+uniqueness |" in out and "best any filter can do at density 95.0" in out


def test_seen_rows_splits_the_measured_pixels_by_what_the_views_see():
    gt = np.full((1, 10), 2.0, np.float32)
    gt[0, 6:9] = 5.0  # covers right columns 1..3, where the background x 3..5 would land: those are hidden
    gt[0, 9] = np.nan
    measured = np.full((1, 10), np.nan, np.float32)
    measured[0, [0, 3, 4, 6, 7]] = [2.0, 9.0, 2.0, 5.0, 1.0]  # x=0 outside (right), x=3 hidden (wrong),
    row = density.seen_rows(measured, gt)                         # x=4 hidden (right), x=6 right, x=7 wrong
    # seen by both: x 2, 6, 7, 8 (x=1 lands on 0 - 1 = -1); measured there: 6, 7 (one wrong)
    assert row["density"] == pytest.approx(100 * 5 / 9) and row["bad2"] == pytest.approx(100 * 2 / 5)
    assert row["seen_share"] == pytest.approx(100 * 2 / 4) and row["seen_bad2"] == pytest.approx(50.0)
    assert row["hidden_measured"] == pytest.approx(100 * 3 / 9) and row["hidden_bad2"] == pytest.approx(100 / 3)
    empty = density.seen_rows(np.full((1, 10), np.nan, np.float32), gt)
    assert empty["density"] == 0.0 and np.isnan(empty["hidden_bad2"]) and np.isnan(empty["bad2"])


def test_compare_table_lines():
    row = {"density": 90.0, "bad2": 4.0, "seen_share": 95.0, "seen_bad2": 2.0, "hidden_measured": 2.0,
           "hidden_bad2": float("nan")}
    lines = density.compare_table({"a": [row, {**row, "density": 80.0, "hidden_bad2": 70.0}]})
    assert lines[0].startswith("| method |") and lines[2] == "| a | 85.0 | 4.00 | 95.0 | 2.00 | 2.00 | 70.0 |"


def test_main_compare(shared_data, capsys):
    assert density.main(["--data", str(shared_data), "--scenes", "tsukuba", "--compare", "ocv-3way"]) == 0
    out = capsys.readouterr().out
    assert "the methods' measured pixels by what the views see" in out and "| ocv-3way |" in out
    assert density.main(["--data", str(shared_data), "--compare", "no-such-method"]) == 2
    assert "--compare" in capsys.readouterr().err
