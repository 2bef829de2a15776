"""The accuracy part of the report: per dataset family, three views, bad-2 and D1 in each, and density.

Reads the ``accuracy`` (scene -> method -> :func:`benchmarks.metrics.scene_metrics` result) and
``accuracy_mean`` (family -> method -> mean) entries of a :func:`benchmarks.run.run_benchmark` report and
returns :class:`benchmarks.report.Section` objects; :mod:`benchmarks.render` writes them.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from typing import Any

from benchmarks.report import Section, Table, fmt
from benchmarks.scenes import FAMILIES, short_name

__all__ = ["ACC_HEADERS", "SUMMARY_HEADERS", "VIEWS_TEXT", "VIEW_LABELS", "accuracy_sections", "bad2_tables", "get",
           "slug", "summary_tables"]

#: The metric views in table order, with their short names (``"all"`` is unknown-is-bad, "ukb").
VIEW_LABELS: tuple[tuple[str, str], ...] = (("dense", "dense"), ("all", "ukb"), ("valid", "valid"))

#: What the three views are, and what this matcher's fill does to them (the report says it once).
VIEWS_TEXT: tuple[str, ...] = (
    ("Three views of every accuracy number (`benchmarks.metrics`), always side by side: **dense** fills every "
    "method's unknown pixels the way the KITTI stereo devkit does before scoring (`interpolateBackground`: each "
    "unknown run in a row takes the smaller of its two known neighbours, borders extrapolated, then columns), "
    "identically for every method, and counts every pixel with ground truth: a method is neither rewarded nor "
    "punished for leaving pixels unknown (the fair view); **ukb** (unknown is bad, the key `all` in report.json) "
    "counts every pixel with ground truth and an unknown one as bad (it rewards density); **valid** counts only "
    "pixels with an estimate (it rewards leaving hard pixels out: read it with the density). D1 is KITTI's "
    "(error > 3 px and > 5 %). Pixels without ground truth never count."),
    ("This project's matcher fills its holes by default (`SGMParams.fill_holes`: the filled map is "
    "`DisparityMap.filled_disparity`, the filled pixels marked in `DisparityMap.filled`), so its dense output has no "
    "unknown pixel: its dense and ukb views score the same filled output and coincide (up to the devkit's fill of a "
    "pixel it did leave unknown). A filled pixel is not a measurement, so its **valid view is computed on the "
    "measured pixels only** (`DisparityMap.disparity`) "
    "and the density beside it (`valid density`) is the measured density. OpenCV's methods return one array, "
    "scored in all three views."),
)

SUMMARY_HEADERS = ["method", "dense bad-2", "dense D1", "ukb bad-2", "ukb D1", "valid bad-2", "valid D1",
                   "density %", "valid density %"]
ACC_HEADERS = SUMMARY_HEADERS + ["dense bad-1", "dense bad-4", "dense EPE [px]", "valid EPE [px]",
                                 "nonocc bad-2 dense", "nonocc bad-2 ukb", "nonocc bad-2 valid",
                                 "border bad-2 dense", "border bad-2 ukb", "border bad-2 valid"]


def slug(text: str) -> str:
    """A file-name-safe version of ``text``."""
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "scene"


def get(d: Any, *keys: str) -> Any:
    """``d[k0][k1]...`` or None where a key is missing."""
    for k in keys:
        if not isinstance(d, Mapping) or k not in d:
            return None
        d = d[k]
    return d


def _summary_cells(acc: Mapping[str, Any]) -> list[str]:
    cells = []
    for view, _ in VIEW_LABELS:
        cells += [fmt(get(acc, "full", view, "bad2")), fmt(get(acc, "full", view, "d1"))]
    return cells + [fmt(get(acc, "full", "all", "density"), 1), fmt(get(acc, "full", "valid", "density"), 1)]


def _acc_row(name: str, acc: Mapping[str, Any]) -> list[str]:
    return [name] + _summary_cells(acc) + [
        fmt(get(acc, "full", "dense", "bad1")), fmt(get(acc, "full", "dense", "bad4")),
        fmt(get(acc, "full", "dense", "epe")), fmt(get(acc, "full", "valid", "epe")),
    ] + [fmt(get(acc, region, view, "bad2")) for region in ("nonocc", "border") for view, _ in VIEW_LABELS]


def _families(report: Mapping[str, Any]) -> dict[str, list[str]]:
    """Family -> its evaluated scenes, in :data:`FAMILIES` order, then report order."""
    family_of = {s["name"]: s.get("family", "other") for s in report.get("scenes", [])}
    out: dict[str, list[str]] = {}
    for family in FAMILIES:
        scenes = [s for s in report.get("accuracy", {}) if family_of.get(s, "other") == family]
        if scenes:
            out[family] = scenes
    return out


def _names(report: Mapping[str, Any]) -> list[str]:
    return [m["name"] for m in report["methods"] if m["available"]]


def summary_tables(report: Mapping[str, Any]) -> list[Table]:
    """One table per dataset family: each method's mean over the family's scenes, three views."""
    tables = []
    means = report.get("accuracy_mean") or {}
    for family, scenes in _families(report).items():
        mean = means.get(family, {})
        rows = [[n] + _summary_cells(mean[n]) for n in _names(report) if n in mean]
        n_scenes = max((v.get("scenes", 0) for v in mean.values()), default=len(scenes))
        tables.append(Table(SUMMARY_HEADERS, rows, f"{family}: bad-2 and D1 %, mean over {n_scenes} scene(s) "
                                                   f"({', '.join(short_name(s) for s in scenes)})"))
    return tables


def bad2_tables(report: Mapping[str, Any]) -> dict[str, dict[str, dict[str, dict[str, float | None]]]]:
    """Per family, what :func:`benchmarks.report.figure_bad2` draws: ``[view][scene][method]`` bad-2, with "mean"."""
    names = _names(report)
    acc = report["accuracy"]
    means = report.get("accuracy_mean") or {}
    out = {}
    for family, scenes in _families(report).items():
        table = {view: {short_name(s): {n: get(acc[s].get(n, {}), "full", view, "bad2") for n in names} for s in scenes}
                 for view, _ in VIEW_LABELS}
        for view, _ in VIEW_LABELS:
            table[view]["mean"] = {n: get(means.get(family, {}).get(n, {}), "full", view, "bad2") for n in names}
        out[family] = table
    return out


def _scene_section(report: Mapping[str, Any], scene: str, names: Sequence[str], figures: Mapping[str, str]) -> Section:
    acc = report["accuracy"][scene]
    info = next((x for x in report["scenes"] if x["name"] == scene), {})
    size = info.get("size", ["?", "?"])
    sec = Section(f"Scene {scene}", level=4)
    sec.paragraphs.append(f"{info.get('family', '?')}; {size[0]}x{size[1]}, {info.get('num_disparities')} disparities, "
                          f"non-occluded mask: {'yes' if info.get('has_nonocc') else 'no'}; source {info.get('source')}.")
    rows = []
    for n in names:
        entry = acc.get(n, {})
        rows.append([n, f"failed: {entry['error']}"] + [""] * (len(ACC_HEADERS) - 2) if "error" in entry
                    else _acc_row(n, entry))
    sec.tables.append(Table(ACC_HEADERS, rows, "percentages unless marked"))
    if f"disp:{scene}" in figures:
        sec.figures.append((figures[f"disp:{scene}"], (f"{scene}: each method's disparity (same colour scale) and "
                                                      "|error| (0-4 px)")))
    return sec


def accuracy_sections(report: Mapping[str, Any], figures: Mapping[str, str]) -> list[Section]:
    """Per family: the mean table, bad-2 per scene in each view, the figure; then a section per scene."""
    acc = report["accuracy"]
    if not acc:
        return [Section("Accuracy", paragraphs=["No scene with ground-truth disparity was evaluated."])]
    names = [m["name"] for m in report["methods"]]
    means = report.get("accuracy_mean") or {}
    out = [Section("Accuracy", paragraphs=list(VIEWS_TEXT) + [
        ("Scenes are grouped by dataset family and averaged per family (each scene weighs the same), never across "
        "families. Regions: the full image, non-occluded pixels (where the dataset has a mask) and the left border "
        "band x < num_disparities (OpenCV leaves it unknown).")])]
    for family, scenes in _families(report).items():
        mean = means.get(family, {})
        sec = Section(f"Accuracy: {family} ({len(scenes)} scene(s))", level=3)
        rows = [_acc_row(n, mean[n]) + [str(mean[n].get("scenes"))] if n in mean
                else [n] + ["n/a"] * (len(ACC_HEADERS) - 1) + ["0"] for n in names]
        sec.tables.append(Table(ACC_HEADERS + ["scenes"], rows, f"{family}: mean over its scenes, percentages unless "
                                                                "marked"))
        for view, label in VIEW_LABELS:
            head = ["method"] + [short_name(s) for s in scenes] + ["mean"]
            trows = [[n] + [fmt(get(acc[s].get(n, {}), "full", view, "bad2")) for s in scenes]
                     + [fmt(get(mean.get(n, {}), "full", view, "bad2"))] for n in names]
            sec.tables.append(Table(head, trows, f"{family}: bad-2 % per scene, view {label}"))
        key = f"bad2:{family}"
        if key in figures:
            sec.figures.append((figures[key], f"{family}: bad-2 per scene and method in the dense, ukb and valid views"))
        out.append(sec)
        out += [_scene_section(report, s, names, figures) for s in scenes]
    return out
