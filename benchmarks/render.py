"""Turn a benchmark result (the dict of :func:`benchmarks.run.run_benchmark`) into the report files."""

from __future__ import annotations

import logging
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.report import (
    Section,
    Table,
    figure_bad2,
    figure_disparities,
    figure_speed,
    fmt,
    have_matplotlib,
    render_html,
    render_markdown,
    write_json_atomic,
    write_text_atomic,
)

__all__ = ["write_report", "summary_markdown", "REPORT_FILES"]

log = logging.getLogger("benchmarks")

REPORT_FILES = ("report.json", "report.md", "report.html")
_TITLE = "stereo_classic benchmark report"
_BASELINES = ("ocv-hh", "ocv-sgbm", "ocv-3way")


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("_") or "scene"


def _get(d: Any, *keys: str) -> Any:
    for k in keys:
        if not isinstance(d, Mapping) or k not in d:
            return None
        d = d[k]
    return d


def _summary_section(report: Mapping[str, Any]) -> Section:
    """Headline numbers, all taken from the tables below (same run)."""
    sec = Section("Summary")
    mean = report.get("accuracy_mean") or {}
    names = [m["name"] for m in report["methods"] if m["available"]]
    if mean:
        rows = [[n, fmt(_get(mean.get(n, {}), "full", "all", "bad2")), fmt(_get(mean.get(n, {}), "full", "valid", "bad2")),
                 fmt(_get(mean.get(n, {}), "full", "all", "d1")), fmt(_get(mean.get(n, {}), "full", "all", "density"), 1)]
                for n in names if n in mean]
        n_scenes = max((v.get("scenes", 0) for v in mean.values()), default=0)
        sec.tables.append(Table(["method", "bad-2 all %", "bad-2 valid %", "D1 all %", "density %"], rows,
                                f"accuracy, mean over {n_scenes} scene(s) with ground truth"))
    speed = [r for r in report["speed"] if r.get("median_ms") is not None]
    if speed:
        size_of = {r["input"]: (r["width"], r["height"], r["num_disparities"]) for r in speed}
        target = next((k for k, v in size_of.items() if v == (1242, 375, 128)), None)
        target = target or max(size_of, key=lambda k: size_of[k][0] * size_of[k][1] * size_of[k][2])
        t_top = max(r["threads"] for r in speed if r["input"] == target)
        sel = {r["method"]: r for r in speed if r["input"] == target and r["threads"] == t_top}
        present = [b for b in _BASELINES if b in sel]
        rows = []
        for n in names:
            if n not in sel:
                continue
            r = sel[n]
            rows.append([n, fmt(r["median_ms"], 1), fmt(r["mde_per_s"], 0)] + [fmt(sel[b]["median_ms"] / r["median_ms"]) for b in present])
        w, h, d = size_of[target]
        sec.tables.append(Table(["method", "ms (median)", "MDE/s"] + [f"x vs {b}" for b in present], rows,
                                f"speed on {target} ({w}x{h}, {d} disparities) at {t_top} thread(s); ratio = baseline ms / method ms"))
    return sec


def _machine_section(report: Mapping[str, Any]) -> Section:
    m = report["machine"]
    cfg = report["config"]
    v = m["versions"]
    sec = Section("Machine and settings")
    sec.paragraphs.append(
        f"Run {m['date_utc']} UTC on **{m['cpu_model']}**, {m['usable_cpus']} usable of {m['logical_cpus']} logical CPUs, "
        f"{fmt(m['memory_gib'], 1)} GiB RAM, {m['os']}, Python {m['python']}; numpy {v.get('numpy')}, numba {v.get('numba')}, "
        f"OpenCV {v.get('cv2')}, onnxruntime {v.get('onnxruntime')}, matplotlib {v.get('matplotlib')}; commit `{m.get('git_commit')}`."
    )
    sec.paragraphs.append(f"Command: `{' '.join(report['command'])}`")
    sec.paragraphs.append(
        f"Every method gets the same pair (as read, BGR; StereoBM gets it in grey), the same disparity range "
        f"(min 0, num = {cfg['disparity_range']}) and block size {cfg['block_size']} (the KITTI OCV-SGBM entry fixes block 3). "
        f"Accuracy is measured on the output of the first call at {cfg['accuracy_threads']} thread(s). "
        f"Speed: {cfg['repeat']} repetitions per method interleaved in a rotating order, after one first call timed apart "
        f"(numba JIT compile or cache load, buffer allocation) and excluded; median with min and max. "
        f"Threads: {cfg['threads']} (cv2.setNumThreads, the matcher's `threads`, onnxruntime intra-op threads)."
    )
    sec.paragraphs.append(
        "Two views of every accuracy number: **all** counts every pixel with ground truth and a pixel the method left "
        "unknown as bad; **valid** counts only pixels with an estimate. EPE and RMS exist only in the valid view; density "
        "is the share of ground-truth pixels with an estimate. Regions: full image, non-occluded (where a mask exists), "
        "and the left border band x < num_disparities. Pixels without ground truth never count."
    )
    for note in report.get("notes", []):
        sec.paragraphs.append(f"Note: {note}")
    return sec


def _methods_section(report: Mapping[str, Any]) -> Section:
    rows = [[m["name"], m["family"], m["description"], "yes" if m["available"] else f"not available: {m['reason']}"] for m in report["methods"]]
    return Section("Methods", tables=[Table(["method", "family", "what", "available"], rows)])


def _acc_row(name: str, acc: Mapping[str, Any]) -> list[str]:
    return [
        name,
        fmt(_get(acc, "full", "all", "bad2")), fmt(_get(acc, "full", "valid", "bad2")),
        fmt(_get(acc, "full", "all", "bad0.5")), fmt(_get(acc, "full", "all", "bad1")), fmt(_get(acc, "full", "all", "bad4")),
        fmt(_get(acc, "full", "all", "d1")), fmt(_get(acc, "full", "valid", "d1")),
        fmt(_get(acc, "full", "valid", "epe")), fmt(_get(acc, "full", "valid", "rms")), fmt(_get(acc, "full", "all", "density"), 1),
        fmt(_get(acc, "nonocc", "all", "bad2")), fmt(_get(acc, "nonocc", "valid", "bad2")),
        fmt(_get(acc, "border", "all", "bad2")), fmt(_get(acc, "border", "valid", "bad2")),
    ]


_ACC_HEADERS = ["method", "bad-2 all", "bad-2 valid", "bad-0.5 all", "bad-1 all", "bad-4 all", "D1 all", "D1 valid",
                "EPE valid [px]", "RMS valid [px]", "density %", "nonocc bad-2 all", "nonocc bad-2 valid",
                "border bad-2 all", "border bad-2 valid"]


def _accuracy_sections(report: Mapping[str, Any], figures: dict[str, str]) -> list[Section]:
    acc = report["accuracy"]
    if not acc:
        return [Section("Accuracy", paragraphs=["No scene with ground-truth disparity was evaluated."])]
    names = [m["name"] for m in report["methods"]]
    scenes = list(acc)
    mean = report["accuracy_mean"]
    sec = Section(f"Accuracy, mean over {len(scenes)} scene(s) with ground truth")
    rows = []
    for n in names:
        if n in mean:
            rows.append(_acc_row(n, mean[n]) + [str(mean[n].get("scenes"))])
        else:
            rows.append([n] + ["n/a"] * (len(_ACC_HEADERS) - 1) + ["0"])
    sec.tables.append(Table(_ACC_HEADERS + ["scenes"], rows, "percentages unless marked; each scene weighs the same"))
    for view, label in (("all", "unknown counted as bad"), ("valid", "valid pixels only")):
        head = ["method"] + scenes + ["mean"]
        trows = []
        for n in names:
            cells = [fmt(_get(acc[s].get(n, {}), "full", view, "bad2")) for s in scenes]
            trows.append([n] + cells + [fmt(_get(mean.get(n, {}), "full", view, "bad2"))])
        sec.tables.append(Table(head, trows, f"bad-2 % per scene, view '{view}' ({label})"))
    if "bad2" in figures:
        sec.figures.append((figures["bad2"], "bad-2 per scene and method, both views"))
    out = [sec]
    for s in scenes:
        info = next((x for x in report["scenes"] if x["name"] == s), {})
        ssec = Section(f"Scene {s}", level=3)
        ssec.paragraphs.append(f"{info.get('size', ['?', '?'])[0]}x{info.get('size', ['?', '?'])[1]}, {info.get('num_disparities')} disparities, "
                               f"non-occluded mask: {'yes' if info.get('has_nonocc') else 'no'}; source {info.get('source')}.")
        rows = []
        for n in names:
            entry = acc[s].get(n, {})
            rows.append([n, f"failed: {entry['error']}"] + [""] * (len(_ACC_HEADERS) - 2) if "error" in entry else _acc_row(n, entry))
        ssec.tables.append(Table(_ACC_HEADERS, rows))
        if f"disp:{s}" in figures:
            ssec.figures.append((figures[f"disp:{s}"], f"{s}: each method's disparity (same colour scale) and |error| (0-4 px)"))
        out.append(ssec)
    return out


def _speed_section(report: Mapping[str, Any], figures: dict[str, str]) -> Section:
    rows = report["speed"]
    sec = Section("Speed")
    sec.paragraphs.append("ms per pair: median [min-max] of the interleaved repetitions; MDE/s = million disparity estimates per "
                          "second (W x H x D / s) at the median; first = the first call (JIT compile or cache load, allocation), excluded. "
                          "Ratios are the baseline's median divided by the method's, same input and thread count, same run.")
    inputs = list(dict.fromkeys(r["input"] for r in rows))
    threads = sorted({r["threads"] for r in rows})
    for inp in inputs:
        sel = [r for r in rows if r["input"] == inp]
        r0 = sel[0]
        head = ["method"]
        for t in threads:
            head += [f"ms t{t}", f"MDE/s t{t}", f"first ms t{t}"]
        t_top = threads[-1]
        present = [b for b in _BASELINES if any(r["method"] == b and r.get("median_ms") for r in sel)]
        head += [f"x vs {b} t{t_top}" for b in present]
        trows = []
        for name in dict.fromkeys(r["method"] for r in sel):
            cells = [name]
            for t in threads:
                hit = next((r for r in sel if r["method"] == name and r["threads"] == t), None)
                if hit is None or hit.get("median_ms") is None:
                    cells += ["n/a" if hit is None else "failed", "", ""]
                else:
                    cells += [f"{hit['median_ms']:.1f} [{hit['min_ms']:.1f}-{hit['max_ms']:.1f}]", fmt(hit["mde_per_s"], 0), fmt(hit["first_call_ms"], 0)]
            me = next((r for r in sel if r["method"] == name and r["threads"] == t_top), {})
            for b in present:
                base = next((r for r in sel if r["method"] == b and r["threads"] == t_top), {})
                cells.append(fmt(base["median_ms"] / me["median_ms"]) if me.get("median_ms") and base.get("median_ms") else "n/a")
            trows.append(cells)
        cap = f"{inp}: {r0['width']}x{r0['height']}, {r0['num_disparities']} disparities ({r0['kind']}: {r0['note']})"
        sec.tables.append(Table(head, trows, cap))
    first_rows = []
    seen: set[str] = set()
    for r in rows:  # rows are in run order: the first row of a method holds its first call in the process
        if r["method"] in seen or r.get("first_call_ms") is None:
            continue
        seen.add(r["method"])
        first_rows.append([r["method"], r["input"], str(r["threads"]), fmt(r["first_call_ms"], 0), fmt(r["median_ms"], 1),
                           fmt(r["first_call_ms"] - r["median_ms"], 0)])
    if first_rows:
        sec.tables.append(Table(["method", "input", "threads", "first call ms", "median ms", "first - median ms"], first_rows,
                                "first call of each method in this process (numba JIT compile or cache load, allocation): "
                                "the compile cost, excluded from the numbers above"))
    if "speed" in figures:
        sec.figures.append((figures["speed"], "median time per method (whiskers min-max), per thread count"))
    return sec


def _memory_section(report: Mapping[str, Any]) -> Section:
    rows = report.get("memory") or []
    sec = Section("Peak memory")
    if not rows:
        sec.paragraphs.append("Not measured in this run.")
        return sec
    how = next((r.get("how") for r in rows if r.get("how")), "")
    isolated = next((r.get("isolated") for r in rows if "isolated" in r), None)
    sec.paragraphs.append(f"Resident-set high water of a child process ({'one per method' if isolated else 'one for all methods, in turn'}); "
                          f"tracemalloc does not see numba's or OpenCV's allocations. How: {how}. "
                          "extra = working memory of the call; bytes/estimate = extra / (W x H x D).")
    trows = []
    for r in rows:
        if "error" in r:
            trows.append([r["input"], r["method"], f"failed: {r['error']}", "", ""])
            continue
        per = (r["extra_mb"] * 2**20) / (r["width"] * r["height"] * r["num_disparities"]) if r.get("extra_mb") is not None else None
        trows.append([r["input"], r["method"], fmt(r["peak_rss_mb"], 0), fmt(r.get("extra_mb"), 0), fmt(per, 2)])
    sec.tables.append(Table(["input", "method", "peak RSS MB", "extra MB", "bytes/estimate"], trows))
    return sec


def _objects_sections(report: Mapping[str, Any]) -> list[Section]:
    out = []
    det = report.get("detectors")
    sec = Section("Detector latency")
    if not det:
        sec.paragraphs.append("Not measured in this run.")
    elif not det.get("available"):
        sec.paragraphs.append(f"Not available: {det.get('reason')}")
    else:
        sec.paragraphs.append(f"{det['how']}; image {det['image_size'][0]}x{det['image_size'][1]}. Stages in ms (median).")
        trows = []
        for r in det["rows"]:
            if "error" in r:
                trows.append([r["model"], str(r.get("threads")), f"failed: {r['error']}", "", "", "", "", ""])
                continue
            size = r.get("input_size")
            size_txt = "x".join(str(v) for v in size) if isinstance(size, (list, tuple)) else fmt(size)
            trows.append([r["model"], str(r["threads"]), f"{r.get('family', '')} {size_txt}".strip(), fmt(r.get("preprocess_ms")),
                          fmt(r.get("inference_ms")), fmt(r.get("postprocess_ms")), fmt(r.get("total_ms")), fmt(r.get("total_p90_ms"))])
        sec.tables.append(Table(["model", "threads", "family / input", "preprocess", "inference", "postprocess", "total", "total p90"], trows))
    out.append(sec)

    pipe = report.get("pipeline")
    sec = Section("Whole pipeline")
    if not pipe:
        sec.paragraphs.append("Not measured in this run.")
    elif not pipe.get("available"):
        sec.paragraphs.append(f"Not available: {pipe.get('reason')}")
    else:
        sec.paragraphs.append(
            f"`stereo_classic.Localizer` (matcher default parameters, {pipe['num_disparities']} disparities, detector {pipe['model']}, "
            f"fusion) on {pipe['scene']} {pipe['size'][0]}x{pipe['size'][1]} at {pipe['threads']} threads: "
            f"**{pipe['fps']:.2f} frames/s** (median {pipe['median_ms']:.1f} ms [{pipe['min_ms']:.1f}-{pipe['max_ms']:.1f}], first call "
            f"{pipe['first_call_ms']:.0f} ms excluded); {pipe.get('objects')} objects.")
        st = pipe.get("stages_median_ms") or {}
        if st:
            sec.tables.append(Table(["stage", "median ms"], [[k, fmt(v, 1)] for k, v in st.items()]))
    out.append(sec)

    dist = report.get("distance") or {}
    sec = Section("Object distance error")
    if not dist:
        sec.paragraphs.append("Not measured in this run.")
    out.append(sec)
    for scene, d in dist.items():
        ssec = Section(f"Distances on {scene}", level=3)
        out.append(ssec)
        if not d.get("available"):
            ssec.paragraphs.append(f"Not available: {d.get('reason')}")
            continue
        methods = list(dict.fromkeys(k for o in d["objects"] for k in o["methods"]))
        ssec.paragraphs.append(f"Detector {d['model']}; reference: {d['reference']}. Cells: fused distance m (error %); "
                               "the fusion is `stereo_classic.localize` on each method's disparity.")
        trows = []
        for o in d["objects"]:
            cells = [f"{o['label']} {o['confidence']:.2f}", fmt(o["reference_m"])]
            for m in methods:
                e = o["methods"].get(m, {})
                if "error" in e:
                    cells.append("failed")
                elif e.get("distance_m") is None:
                    cells.append(e.get("status", "n/a"))
                else:
                    cells.append(f"{e['distance_m']:.2f} ({fmt(e.get('error_pct'), 1)} %)")
            trows.append(cells)
        mean_row = ["mean abs error %", ""]
        for m in methods:
            errs = [o["methods"][m]["error_pct"] for o in d["objects"] if "error_pct" in o["methods"].get(m, {})]
            mean_row.append(f"{np.mean(errs):.1f} ({len(errs)}/{len(d['objects'])})" if errs else "n/a")
        trows.append(mean_row)
        ssec.tables.append(Table(["object", "reference m"] + methods, trows))
    return out


def _errors_section(report: Mapping[str, Any]) -> Section | None:
    errs = report.get("errors") or {}
    if not errs:
        return None
    rows = [[scene, m, e] for scene, d in errs.items() for m, e in d.items()]
    return Section("Failures", tables=[Table(["scene", "method", "error"], rows)])


def _make_figures(report: Mapping[str, Any], arrays: Mapping[str, Any], out_dir: Path) -> tuple[dict[str, str], str | None]:
    reason = have_matplotlib()
    if reason is not None:
        return {}, reason
    figures: dict[str, str] = {}
    for name, item in arrays.get("scenes", {}).items():
        scene = item["scene"]
        if not item["outputs"]:
            continue
        fname = f"disparity_{_slug(name)}.png"
        vmax = float(np.nanmax(scene.gt_disparity)) if scene.gt_disparity is not None and np.isfinite(scene.gt_disparity).any() else float(item["ndisp"])
        try:
            figure_disparities(out_dir / fname, name, scene.left, scene.gt_disparity, item["outputs"], vmax=vmax)
            figures[f"disp:{name}"] = fname
        except Exception as exc:  # noqa: BLE001 - a figure must not lose the numbers
            log.warning("figure for %s failed: %s", name, exc)
    acc = report["accuracy"]
    if acc:
        names = [m["name"] for m in report["methods"] if m["available"]]
        table = {view: {s: {n: _get(acc[s].get(n, {}), "full", view, "bad2") for n in names} for s in acc} for view in ("all", "valid")}
        for view in table:
            table[view]["mean"] = {n: _get(report["accuracy_mean"].get(n, {}), "full", view, "bad2") for n in names}
        try:
            figure_bad2(out_dir / "bad2.png", table)
            figures["bad2"] = "bad2.png"
        except Exception as exc:  # noqa: BLE001
            log.warning("bad-2 figure failed: %s", exc)
    rows = [r for r in report["speed"] if r.get("median_ms") is not None]
    if rows:
        by_size: dict[str, int] = {}
        for r in rows:
            by_size[r["input"]] = r["width"] * r["height"] * r["num_disparities"]
        chosen = [k for k, _ in sorted(by_size.items(), key=lambda kv: -kv[1])[:2]]
        try:
            figure_speed(out_dir / "speed.png", rows, chosen)
            if (out_dir / "speed.png").is_file():
                figures["speed"] = "speed.png"
        except Exception as exc:  # noqa: BLE001
            log.warning("speed figure failed: %s", exc)
    return figures, None


def write_report(report: dict[str, Any], arrays: Mapping[str, Any], out_dir: Path, *, figures: bool = True) -> list[Path]:
    """Write report.json, report.md, report.html and the PNG figures into ``out_dir``; returns the paths written."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    figs: dict[str, str] = {}
    if figures:
        figs, reason = _make_figures(report, arrays, out_dir)
        if reason is not None:
            msg = f"matplotlib (the `bench` extra) is not usable ({reason}): no figures; pip install 'stereo-classic[bench]'"
            log.warning(msg)
            report.setdefault("notes", []).append(msg)
    else:
        report.setdefault("notes", []).append("figures switched off (--no-figures)")
    report["figures"] = figs
    sections = [_summary_section(report), _machine_section(report), _methods_section(report)]
    sections += _accuracy_sections(report, figs)
    sections.append(_speed_section(report, figs))
    sections.append(_memory_section(report))
    sections += _objects_sections(report)
    err = _errors_section(report)
    if err is not None:
        sections.append(err)
    write_json_atomic(out_dir / "report.json", report)
    write_text_atomic(out_dir / "report.md", render_markdown(_TITLE, sections))
    write_text_atomic(out_dir / "report.html", render_html(_TITLE, sections, out_dir))
    return [out_dir / f for f in REPORT_FILES] + [out_dir / f for f in figs.values()]


def summary_markdown(report: Mapping[str, Any]) -> str:
    """The summary tables (mean accuracy, speed ratios) of a report.json as Markdown, with the machine line.

    ``python -m benchmarks.render bench_out/report.json`` prints it (for the README's results table).
    """
    m = report["machine"]
    sec = _summary_section(report)
    sec.paragraphs.insert(0, f"Measured {m['date_utc']} UTC on {m['cpu_model']} ({m['usable_cpus']} CPUs), OpenCV "
                             f"{m['versions'].get('cv2')}, numba {m['versions'].get('numba')}, commit `{m.get('git_commit')}`, "
                             f"with `{' '.join(report['command'])}`.")
    return render_markdown("Results", [sec]).split("\n", 2)[2]


if __name__ == "__main__":
    import json
    import sys

    if len(sys.argv) != 2:
        print("usage: python -m benchmarks.render REPORT.json", file=sys.stderr)
        sys.exit(2)
    try:
        data = json.loads(Path(sys.argv[1]).read_text(encoding="utf-8"))
        print(summary_markdown(data))
    except (OSError, ValueError, KeyError) as exc:
        print(f"error: {sys.argv[1]}: {exc}", file=sys.stderr)
        sys.exit(1)
