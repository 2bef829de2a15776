"""Turn a benchmark result (the dict of :func:`benchmarks.run.run_benchmark`) into the report files."""

from __future__ import annotations

import logging
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.render_accuracy import (
    VIEW_LABELS,
    accuracy_sections,
    bad2_tables,
    summary_tables,
)
from benchmarks.render_accuracy import get as _get
from benchmarks.render_accuracy import slug as _slug
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

__all__ = ["README_METHODS", "REPORT_FILES", "markdown_sections", "readme_markdown", "summary_markdown", "write_report"]

log = logging.getLogger("benchmarks")

REPORT_FILES = ("report.json", "report.md", "report.html")
_TITLE = "stereo_classic benchmark report"
_BASELINES = ("ocv-hh", "ocv-sgbm", "ocv-3way")


def _summary_section(report: Mapping[str, Any]) -> Section:
    """Headline numbers, all taken from the tables below (same run)."""
    sec = Section("Summary")
    names = [m["name"] for m in report["methods"] if m["available"]]
    sec.tables += summary_tables(report)
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
            rows.append([n, fmt(r["median_ms"], 1), fmt(r.get("cpu_median_ms"), 1), fmt(r["mde_per_s"], 0)]
                        + [fmt(sel[b]["median_ms"] / r["median_ms"]) for b in present])
        w, h, d = size_of[target]
        sec.tables.append(Table(["method", "ms (median)", "CPU ms (median)", "MDE/s"] + [f"x vs {b}" for b in present], rows,
                                f"speed on {target} ({w}x{h}, {d} disparities, grey) at {t_top} thread(s); ratio = baseline ms / method ms; "
                                f"CPU ms = process CPU time per call (all threads)"))
    scaling = report.get("scaling") or {}
    if scaling.get("available"):
        sec.tables.append(_scaling_table(scaling, compact=True))
    pipe = [p for p in _pipeline_rows(report) if p.get("available")]
    if pipe:
        inputs = list(dict.fromkeys((p["scene"], tuple(p["size"]), p["num_disparities"]) for p in pipe))
        rows = []
        for scene, size, ndisp in inputs:
            sel = {bool(p.get("concurrent")): p for p in pipe if (p["scene"], tuple(p["size"]), p["num_disparities"]) == (scene, size, ndisp)}
            rows.append([scene, f"{size[0]}x{size[1]}x{ndisp}", fmt(sel[False]["fps"], 1) if False in sel else "n/a",
                         fmt(sel[True]["fps"], 1) if True in sel else "n/a"])
        sec.tables.append(Table(["pipeline input", "WxHxD", "frames/s", "frames/s, detector concurrent"], rows,
                                f"whole pipeline (`stereo_classic.Localizer`: matcher defaults, detector {pipe[0]['model']}, "
                                f"fusion, frame checks) at 2 threads"))
    return sec


def _pipeline_rows(report: Mapping[str, Any]) -> list[dict[str, Any]]:
    pipe = report.get("pipeline")
    if not pipe:
        return []
    return [pipe] if isinstance(pipe, Mapping) else list(pipe)  # a report of schema 1 held one dict


def _scaling_table(sc: Mapping[str, Any], *, compact: bool = False) -> Table:
    """The thread-scaling table; ``compact``: ms, speed-up and identity per method in one row per thread count."""
    methods = list(sc["methods"])
    by = {(r["method"], r["threads"]): r for r in sc["rows"]}
    cap = (f"thread scaling on {sc['input']} ({sc['width']}x{sc['height']}, {sc['num_disparities']} disparities), "
           f"{sc['cores']} usable cores; speed-up = ms at 1 thread / ms (medians; fastest calls: the fastest call at 1 "
           f"thread / the fastest call); efficiency = speed-up / min(threads, cores); "
           f"identical = output bit-identical to 1 thread")
    if compact:
        head = ["threads"] + [f"{m} {k}" for m in methods for k in ("ms", "speed-up", "CPU s")]
        head += ([f"{methods[0]} x vs {methods[-1]}"] if len(methods) > 1 else []) + ["identical to 1 thread"]
        rows = []
        for t in sc["threads"]:
            cells = [str(t)]
            for m in methods:
                r = by.get((m, t), {})
                cells += [fmt(r.get("median_ms"), 1), fmt(r.get("speedup")), fmt(r.get("cpu_s_per_call"), 3)]
            if len(methods) > 1:
                a, b = by.get((methods[0], t), {}), by.get((methods[-1], t), {})
                cells.append(fmt(b["median_ms"] / a["median_ms"]) if a.get("median_ms") and b.get("median_ms") else "n/a")
            cells.append(", ".join(f"{m} {'yes' if by.get((m, t), {}).get('identical') else 'NO'}" for m in methods))
            rows.append(cells)
        return Table(head, rows, cap)
    head = ["method", "threads", "ms median [min-max]", "speed-up", "speed-up, fastest calls", "efficiency",
            "CPU s per call", "CPU vs 1 thread", "identical to 1 thread", "first call ms"]
    rows = [[r["method"], str(r["threads"]), f"{fmt(r['median_ms'], 1)} [{fmt(r['min_ms'], 1)}-{fmt(r['max_ms'], 1)}]",
             fmt(r["speedup"]), fmt(r.get("speedup_best")), fmt(r["efficiency"]), fmt(r["cpu_s_per_call"], 3), fmt(r.get("cpu_ratio")),
             "yes" if r["identical"] else "NO", fmt(r.get("first_call_ms"), 0)]
            for m in methods for r in sc["rows"] if r["method"] == m]
    return Table(head, rows, cap)


def _scaling_section(report: Mapping[str, Any]) -> Section:
    sc = report.get("scaling")
    sec = Section("Thread scaling")
    if not sc:
        sec.paragraphs.append("Not measured in this run.")
    elif not sc.get("available"):
        sec.paragraphs.append(f"Not available: {sc.get('reason')}")
    else:
        sec.paragraphs.append(f"The matcher's defaults (`sc-default`) and OpenCV MODE_SGBM_3WAY (`ocv-3way`) at 1..cores threads "
                              f"and at 2, 4 and 8 even beyond the cores (oversubscription), on {sc.get('note', sc['input'])}. "
                              f"How: {sc['how']}.")
        sec.tables.append(_scaling_table(sc))
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
        f"Speed: on the grey pair (a network: the pair as read; OpenCV makes its cost from every channel of a colour pair, "
        f"this matcher and Pandora read grey, so grey is the same work for all), "
        f"{cfg['repeat']} repetitions per method interleaved in a rotating order, after one first call timed apart "
        f"(numba JIT compile or cache load, buffer allocation) and excluded; median with min and max. "
        f"Threads: {cfg['threads']} (cv2.setNumThreads, the matcher's `threads`, onnxruntime intra-op threads)."
    )
    sec.paragraphs.append("Accuracy has three views (dense, ukb, valid), explained at the top of the Accuracy section.")
    for note in report.get("notes", []):
        sec.paragraphs.append(f"Note: {note}")
    return sec


def _methods_section(report: Mapping[str, Any]) -> Section:
    rows = [[m["name"], m["family"], m["description"], "yes" if m["available"] else f"not available: {m['reason']}"] for m in report["methods"]]
    return Section("Methods", tables=[Table(["method", "family", "what", "available"], rows)])


def _speed_section(report: Mapping[str, Any], figures: dict[str, str]) -> Section:
    rows = report["speed"]
    sec = Section("Speed")
    sec.paragraphs.append("ms per pair: median [min-max] of the interleaved repetitions; MDE/s = million disparity estimates per "
                          "second (W x H x D / s) at the median; first = the first call (JIT compile or cache load, allocation), excluded. "
                          "Ratios are the baseline's median divided by the method's, same input and thread count, same run. "
                          "Every classical method is timed on the grey pair (OpenCV's StereoSGBM makes its cost from every "
                          "channel of a colour pair; this matcher and Pandora read grey), a network on the pair as read.")
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

    pipe = _pipeline_rows(report)
    sec = Section("Whole pipeline")
    if not pipe:
        sec.paragraphs.append("Not measured in this run.")
    else:
        sec.paragraphs.append(
            "`stereo_classic.Localizer` as `run` uses it (matcher default parameters, frame checks on, fusion), the "
            "default detector, 2 threads: frames/s = 1000 / median ms of repeated calls on the same pair, first call "
            "excluded. `concurrent`: the Localizer runs the detector in a worker thread while the matcher runs.")
        trows = []
        stage_names: list[str] = []
        for p in pipe:
            stage_names += [k for k in (p.get("stages_median_ms") or {}) if k not in stage_names]
        for p in pipe:
            if not p.get("available"):
                trows.append([str(p.get("input", "?")), "", "", f"not available: {p.get('reason')}"] + [""] * (3 + len(stage_names)))
                continue
            st = p.get("stages_median_ms") or {}
            trows.append([p.get("input", p["scene"]), f"{p['size'][0]}x{p['size'][1]}x{p['num_disparities']}",
                          "yes" if p.get("concurrent") else "no", p["model"] or "none", f"**{p['fps']:.2f}**",
                          f"{p['median_ms']:.1f} [{p['min_ms']:.1f}-{p['max_ms']:.1f}]", str(p.get("objects"))]
                         + [fmt(st.get(k), 1) for k in stage_names])
        sec.tables.append(Table(["input", "WxHxD", "concurrent", "detector", "frames/s", "ms median [min-max]", "objects"]
                                + [f"{k} ms" for k in stage_names], trows, "stage columns: median ms per call"))
    out.append(sec)

    out.append(_pipeline_table_section(report))
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


def _pipeline_table_section(report: Mapping[str, Any]) -> Section:
    """``run`` and ``guide`` frame by frame: stage median ms / CPU ms, frames/s, latency (benchmarks.pipeline_table)."""
    from benchmarks.pipeline_table import format_table

    table = report.get("pipeline_table") or {"available": False, "reason": "not measured in this run"}
    sec = Section("Pipeline stages of run and guide")
    if table.get("available"):
        sec.paragraphs.append(f"{table['how']}. Cells: median wall ms / mean process CPU ms per frame (all threads).")
    sec.paragraphs.append(format_table(table))
    return sec


def markdown_sections(title: str, text: str, *, level: int = 2) -> list[Section]:
    """Sections from Markdown made elsewhere: pipe tables become tables, other non-empty lines paragraphs.

    Lines after a table go into a following section ("<title>: notes", one level down), so the order holds.
    """
    sec = Section(title, level=level)
    out = [sec]
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        line = lines[i].strip()
        if line.startswith("|"):
            block = []
            while i < len(lines) and lines[i].strip().startswith("|"):
                block.append([c.strip() for c in lines[i].strip().strip("|").split("|")])
                i += 1
            body = [r for r in block[1:] if not all(set(c) <= set("-: ") for c in r)]
            sec.tables.append(Table(block[0], body))
            continue
        if line:
            if sec.tables:
                sec = Section(f"{title}: notes", level=level + 1)
                out.append(sec)
            sec.paragraphs.append(line)
        i += 1
    return out


def _kitti_objects_sections(report: Mapping[str, Any]) -> list[Section]:
    res = report.get("kitti_objects")
    title = "Per-object distance against KITTI labels"
    if not res:
        return [Section(title, paragraphs=["Not measured in this run."])]
    from benchmarks.kitti_objects import render_markdown as kitti_markdown

    out = markdown_sections(title, kitti_markdown(res))
    if res.get("available"):
        out[0].paragraphs.insert(0, "`benchmarks.kitti_objects` (also `python -m benchmarks.kitti_objects`), 2 threads: for each "
                                 "labelled car the reference is the LiDAR points inside its labelled 3D box; `run` = the "
                                 "Localizer as `run` builds it, 3WAY + fusion = OpenCV MODE_SGBM_3WAY with the same fusion, "
                                 "DepthAI median = median of the measured disparity in the half-size box. Errors signed, %.")
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
    for family, table in bad2_tables(report).items():
        fname = f"bad2_{_slug(family)}.png"
        try:
            figure_bad2(out_dir / fname, table, labels=dict(VIEW_LABELS), title=family)
            figures[f"bad2:{family}"] = fname
        except Exception as exc:  # noqa: BLE001
            log.warning("bad-2 figure of %s failed: %s", family, exc)
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
    sections += accuracy_sections(report, figs)
    sections.append(_speed_section(report, figs))
    sections.append(_scaling_section(report))
    sections.append(_memory_section(report))
    sections += _objects_sections(report)
    sections += _kitti_objects_sections(report)
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


#: Methods of the README table: the default against every OpenCV SGBM mode and the accuracy peer (when installed), and
#: the default's most accurate setting (``lr_mode="independent"``, 1.5-1.9 times its time).
README_METHODS: tuple[str, ...] = ("sc-default", "sc-independent", "ocv-sgbm", "ocv-hh", "ocv-3way", "ocv-hh4", "pandora")
#: Methods that run on one thread whatever the benchmark's thread count (their times say so).
SINGLE_THREADED: frozenset[str] = frozenset({"pandora"})


#: The sizes of the README's speed lines: the KITTI pair and VGA (the frame-rate issue's two).
README_SPEED_SIZES: tuple[tuple[int, int, int], ...] = ((1242, 375, 128), (640, 480, 64))


def _speed_line(report: Mapping[str, Any], size: tuple[int, int, int] = (1242, 375, 128)) -> str | None:
    rows = [r for r in report.get("speed", []) if r.get("median_ms") is not None
            and (r["width"], r["height"], r["num_disparities"]) == tuple(size)]
    if not rows:
        return None
    t = 2 if any(r["threads"] == 2 for r in rows) else max(r["threads"] for r in rows)
    sel = {r["method"]: r for r in rows if r["threads"] == t}
    if "sc-default" not in sel:
        return None
    me = sel["sc-default"]["median_ms"]
    parts = [f"`{b}` {sel[b]['median_ms']:.1f} ms{' single-threaded' if b in SINGLE_THREADED else ''} "
             f"({sel[b]['median_ms'] / me:.2f}x)" for b in README_METHODS[1:] if b in sel]
    return (f"**Speed** at {size[0]}x{size[1]}x{size[2]}, grey pair, {t} thread(s), median: `sc-default` {me:.1f} ms; "
            + ", ".join(parts) + " (x = their ms / ours).")


def _scaling_line(report: Mapping[str, Any]) -> str | None:
    sc = report.get("scaling") or {}
    if not sc.get("available"):
        return None
    by = {(r["method"], r["threads"]): r for r in sc["rows"]}
    counts = sc["threads"]
    parts = []
    for m in sc["methods"]:
        ms = " / ".join(fmt(by.get((m, t), {}).get("median_ms"), 1) for t in counts)
        up = " / ".join(fmt(by.get((m, t), {}).get("speedup")) for t in counts)
        best = " / ".join(fmt(by.get((m, t), {}).get("speedup_best")) for t in counts)
        parts.append(f"`{m}` {ms} ms (speed-up {up}; fastest calls {best})")
    top = counts[-1]
    cpu = by.get(("sc-default", top), {}).get("cpu_ratio")
    same = all(r["identical"] for r in sc["rows"] if r["method"] == "sc-default")
    return (f"**Thread scaling** on the KITTI pair in grey ({sc['cores']} usable cores), threads {' / '.join(map(str, counts))}: "
            + "; ".join(parts) + f". `sc-default` CPU time per call at {top} threads: {fmt(cpu)}x that at 1 thread; output "
            f"bit-identical at every thread count: {'yes' if same else 'no'}.")


def readme_markdown(report: Mapping[str, Any]) -> str:
    """The README's results block: per family the default against every OpenCV mode in three views, speed, scaling.

    ``python -m benchmarks.render bench_out/report.json`` prints it; ``--full`` prints :func:`summary_markdown`.
    """
    m = report["machine"]
    lines = [(f"Measured {m['date_utc']} UTC on {m['cpu_model']} ({m['usable_cpus']} CPUs), OpenCV "
             f"{m['versions'].get('cv2')}, numba {m['versions'].get('numba')}, commit `{m.get('git_commit')}`, with "
             f"`{' '.join(report['command'])}`. bad-2 % (lower is better), mean per family:"), "",
             "| scenes | method | dense | ukb | valid | valid density % |", "|---|---|---|---|---|---|"]
    means = report.get("accuracy_mean") or {}
    for family, per_method in means.items():
        n = max((v.get("scenes", 0) for v in per_method.values()), default=0)
        first = True
        for name in README_METHODS:
            if name not in per_method:
                continue
            acc = per_method[name]
            cells = [fmt(_get(acc, "full", view, "bad2")) for view, _ in VIEW_LABELS]
            lines.append(f"| {f'{family} ({n})' if first else ''} | {name} | " + " | ".join(cells)
                         + f" | {fmt(_get(acc, 'full', 'valid', 'density'), 1)} |")
            first = False
    lines.append("")
    for extra in (*(_speed_line(report, size) for size in README_SPEED_SIZES), _scaling_line(report)):
        if extra:
            lines += [extra, ""]
    pipe = [p for p in _pipeline_rows(report) if p.get("available") and not p.get("concurrent")]
    if pipe:
        lines += ["**Pipeline** (Localizer, default detector, 2 threads): " + "; ".join(
            f"{p['size'][0]}x{p['size'][1]}x{p['num_disparities']} {p['fps']:.1f} frames/s" for p in pipe) + ".", ""]
    table = report.get("pipeline_table") or {}
    if table.get("available"):
        from benchmarks.pipeline_table import format_table

        lines += ["**`run` and `guide`, frame by frame** (read to record written; cells: median ms / process CPU ms "
                  "per frame):", "", format_table(table), ""]
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    """``python -m benchmarks.render [--full] REPORT.json``: 0 printed, 1 unreadable report, 2 usage error."""
    import argparse
    import json

    parser = argparse.ArgumentParser(prog="python -m benchmarks.render",
                                     description="Print the README's results block of a benchmark report.")
    parser.add_argument("report", metavar="REPORT.json", help="the report.json of `python -m benchmarks`")
    parser.add_argument("--full", action="store_true", help="the summary tables instead of the README's block")
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    try:
        data = json.loads(Path(args.report).read_text(encoding="utf-8"))
        print(summary_markdown(data) if args.full else readme_markdown(data))
    except (OSError, ValueError, KeyError) as exc:
        print(f"error: {args.report}: {exc}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
