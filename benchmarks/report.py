"""Report writers: report.json (every raw number), report.md, report.html (self-contained) and PNG figures.

The report is built as a list of sections (heading, paragraphs, tables, figures) and rendered to
Markdown and to HTML from the same data, so both say the same thing. matplotlib (the ``bench`` extra)
is imported lazily; without it the figures are skipped and the report says so.
"""

from __future__ import annotations

import base64
import html
import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "Table",
    "Section",
    "render_markdown",
    "render_html",
    "write_text_atomic",
    "write_json_atomic",
    "jsonable",
    "fmt",
    "signed_zero_free",
    "figure_disparities",
    "figure_bad2",
    "figure_speed",
    "have_matplotlib",
]


@dataclass
class Table:
    """A table: header cells and rows of already formatted cells."""

    headers: list[str]
    rows: list[list[str]]
    caption: str = ""


@dataclass
class Section:
    """A report section."""

    title: str
    paragraphs: list[str] = field(default_factory=list)
    tables: list[Table] = field(default_factory=list)
    figures: list[tuple[str, str]] = field(default_factory=list)  # (file name, caption)
    level: int = 2


def signed_zero_free(text: str, spec: str) -> str:
    """``text`` (a number formatted with ``spec``) with a zero that rounding left signed written unsigned: a table
    never shows "-0.0" (a value of -0.04 at one decimal is 0.0, not a negative error).

    >>> signed_zero_free(format(-0.04, "+.1f"), "+.1f"), signed_zero_free(format(-0.04, ".1f"), ".1f")
    ('+0.0', '0.0')
    """
    try:
        zero = float(text) == 0.0
    except ValueError:
        return text
    return format(0.0, spec) if zero else text


def fmt(value: Any, digits: int = 2) -> str:
    """A number for a table cell; ``None``/NaN -> "n/a"; never "-0.00"."""
    if value is None:
        return "n/a"
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(float(value)):
            return "n/a"
        return signed_zero_free(f"{float(value):.{digits}f}", f".{digits}f")
    return str(value)


def jsonable(value: Any) -> Any:
    """A copy of ``value`` that ``json.dumps(allow_nan=False)`` accepts: NaN/inf -> None, numpy -> python."""
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(float(value)) else None
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, Path):
        return str(value)
    return repr(value)


def _atomic_bytes(path: Path, data: bytes) -> None:
    from stereo_classic.io import atomic_write

    with atomic_write(Path(path), mode="wb") as fh:
        fh.write(data)


def write_text_atomic(path: Path, text: str) -> None:
    """Write text (UTF-8) atomically: temp file in the same folder, then rename."""
    _atomic_bytes(Path(path), text.encode("utf-8"))


def write_json_atomic(path: Path, data: Any) -> None:
    """Write ``data`` as JSON (NaN/inf as null) atomically."""
    write_text_atomic(Path(path), json.dumps(jsonable(data), indent=1, allow_nan=False) + "\n")


def _md_cell(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def render_markdown(title: str, sections: Sequence[Section]) -> str:
    """Markdown of the report (figures linked by file name, next to report.md)."""
    lines = [f"# {title}", ""]
    for sec in sections:
        lines += ["#" * sec.level + " " + sec.title, ""]
        for par in sec.paragraphs:
            lines += [par, ""]
        for table in sec.tables:
            if table.caption:
                lines += [f"*{table.caption}*", ""]
            lines.append("| " + " | ".join(_md_cell(h) for h in table.headers) + " |")
            lines.append("|" + "|".join("---" for _ in table.headers) + "|")
            for row in table.rows:
                lines.append("| " + " | ".join(_md_cell(c) for c in row) + " |")
            lines.append("")
        for name, caption in sec.figures:
            lines += [f"![{caption}]({name})", "", f"*{caption}*", ""]
    return "\n".join(lines)


_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;margin:2em auto;max-width:1300px;padding:0 1em;color:#222}
table{border-collapse:collapse;margin:0.6em 0 1.4em 0;font-size:0.86em}
th,td{border:1px solid #ccc;padding:3px 7px;text-align:right}
th{background:#f1f1f1}td:first-child,th:first-child{text-align:left}
tr:nth-child(even) td{background:#fafafa}
img{max-width:100%;border:1px solid #ddd}
figcaption,caption{font-style:italic;color:#555;text-align:left;padding:4px 0}
code{background:#f4f4f4;padding:0 3px}
"""


def render_html(title: str, sections: Sequence[Section], figure_dir: Path) -> str:
    """Self-contained HTML: same content as the Markdown, figures embedded as base64 PNG."""
    out = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
    ]
    for sec in sections:
        lvl = max(2, min(6, sec.level))
        out.append(f"<h{lvl}>{html.escape(sec.title)}</h{lvl}>")
        for par in sec.paragraphs:
            out.append(f"<p>{_inline(par)}</p>")
        for table in sec.tables:
            out.append("<table>")
            if table.caption:
                out.append(f"<caption>{_inline(table.caption)}</caption>")
            out.append("<tr>" + "".join(f"<th>{html.escape(str(h))}</th>" for h in table.headers) + "</tr>")
            for row in table.rows:
                out.append("<tr>" + "".join(f"<td>{_inline(str(c))}</td>" for c in row) + "</tr>")
            out.append("</table>")
        for name, caption in sec.figures:
            path = Path(figure_dir) / name
            if not path.is_file():
                continue
            data = base64.b64encode(path.read_bytes()).decode("ascii")
            out.append(f'<figure><img alt="{html.escape(caption)}" src="data:image/png;base64,{data}"><figcaption>{html.escape(caption)}</figcaption></figure>')
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def _inline(text: str) -> str:
    """Escape HTML and turn Markdown `code` and **bold** into tags."""
    escaped = html.escape(text)
    parts = escaped.split("`")
    escaped = "".join(f"<code>{p}</code>" if i % 2 else p for i, p in enumerate(parts))
    parts = escaped.split("**")
    return "".join(f"<b>{p}</b>" if i % 2 else p for i, p in enumerate(parts))


# ----------------------------------------------------------------------------------------- figures


def have_matplotlib() -> str | None:
    """None when matplotlib can be used, else the reason it cannot."""
    try:
        import matplotlib

        matplotlib.use("Agg", force=True)
        import matplotlib.pyplot  # noqa: F401
    except Exception as exc:  # noqa: BLE001 - any import failure means "no figures"
        return f"{type(exc).__name__}: {exc}"
    return None


def _save(fig: Any, path: Path, dpi: int) -> None:
    import io

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=dpi, bbox_inches="tight")
    _atomic_bytes(Path(path), buf.getvalue())


def figure_disparities(
    path: Path,
    scene_name: str,
    left: np.ndarray,
    gt: np.ndarray | None,
    outputs: Mapping[str, np.ndarray],
    *,
    vmax: float,
    err_max: float = 4.0,
    per_row: int = 2,
    dpi: int = 60,
) -> None:
    """Per scene: every method's disparity beside its absolute error map, one colour scale for all.

    Disparity in TURBO from 0 to ``vmax`` (black: unknown); |error| from 0 (light yellow) to
    ``err_max`` px or more (dark red), black where the method left a ground-truth pixel unknown, grey
    where there is no ground truth. ``per_row`` methods per row, each as a (disparity, error) pair.
    """
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    panels: list[tuple[str, str, np.ndarray | None]] = [("left image", "image", None)]
    if gt is not None:
        panels.append(("ground truth", "disp", gt))
    panels_per_row = 2 * per_row
    first_row = panels + [("", "blank", None)] * (panels_per_row - len(panels))
    rows_spec = [first_row]
    items = list(outputs.items())
    step = per_row if gt is not None else panels_per_row  # without ground truth: disparities only
    for k in range(0, len(items), step):
        row = []
        for name, disp in items[k:k + step]:
            row.append((name, "disp", disp))
            if gt is not None:
                row.append((f"{name} |error|", "err", disp))
        row += [("", "blank", None)] * (panels_per_row - len(row))
        rows_spec.append(row)
    h, w = left.shape[:2]
    panel_w = 3.2
    panel_h = panel_w * h / w + 0.3
    fig, axes = plt.subplots(len(rows_spec), panels_per_row, figsize=(panel_w * panels_per_row, panel_h * len(rows_spec) + 0.9), squeeze=False)
    turbo = plt.get_cmap("turbo").with_extremes(bad="black")
    errmap = plt.get_cmap("YlOrRd")
    has_gt = np.isfinite(gt) if gt is not None else None
    for r, row in enumerate(rows_spec):
        for c, (label, kind, disp) in enumerate(row):
            ax = axes[r][c]
            ax.set_xticks([])
            ax.set_yticks([])
            if kind == "blank":
                ax.set_visible(False)
                continue
            if kind == "image":
                ax.imshow(left[:, :, ::-1] if left.ndim == 3 else left, cmap=None if left.ndim == 3 else "gray")
            elif kind == "disp":
                ax.imshow(np.ma.masked_invalid(disp), cmap=turbo, vmin=0, vmax=vmax, interpolation="nearest")
            else:
                err = np.abs(disp.astype(np.float32) - gt)
                img = np.full(gt.shape + (3,), 0.6, np.float32)  # grey: no ground truth
                known = has_gt & np.isfinite(disp)
                unknown = has_gt & ~np.isfinite(disp)
                colours = errmap(np.clip(np.nan_to_num(err, nan=0.0) / err_max, 0, 1))[..., :3]
                img[known] = colours[known]
                img[unknown] = 0.0
                ax.imshow(img, interpolation="nearest")
            ax.set_title(label, fontsize=8)
    title = f"{scene_name}: disparity 0-{vmax:.0f} px (black = unknown)"
    if gt is not None:
        title += f"; |error| 0-{err_max:g} px (black = unknown, grey = no ground truth)"
    fig.suptitle(title, fontsize=10)
    fig.tight_layout(rect=(0, 0.04, 1, 0.98))
    cax = fig.add_axes((0.06, 0.012, 0.4, 0.008))
    fig.colorbar(ScalarMappable(Normalize(0, vmax), turbo), cax=cax, orientation="horizontal", label="disparity [px]")
    if gt is not None:
        cax = fig.add_axes((0.54, 0.012, 0.4, 0.008))
        fig.colorbar(ScalarMappable(Normalize(0, err_max), errmap), cax=cax, orientation="horizontal", label="|error| [px]")
    _save(fig, path, dpi)
    plt.close(fig)


def figure_bad2(path: Path, table: Mapping[str, Mapping[str, Mapping[str, float | None]]], *,
                labels: Mapping[str, str] | None = None, title: str = "", dpi: int = 90) -> None:
    """bad-2 per scene, one bar per method, one panel per view: ``table[view][scene][method]``.

    Views are drawn in the order "dense", "all", "valid" (those present); ``labels`` names them in the titles
    (e.g. {"all": "ukb"}); ``title`` prefixes every panel title (a dataset family).
    """
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    what = {"dense": "unknown filled as the KITTI devkit does", "all": "unknown counted as bad", "valid": "valid pixels only"}
    labels = dict(labels or {})
    views = [v for v in ("dense", "all", "valid") if v in table]
    scenes = list(table[views[0]].keys()) if views else []
    methods: list[str] = []
    for view in views:
        for scene in scenes:
            methods += [m for m in table[view][scene] if m not in methods]
    fig, axes = plt.subplots(len(views), 1, figsize=(max(8.0, 1.1 * len(scenes) * max(1, len(methods)) * 0.18 + 3),
                                                     3.2 * len(views) + 0.8), squeeze=False)
    cmap = plt.get_cmap("tab20")
    width = 0.8 / max(1, len(methods))
    top = max([v for view in views for sc in scenes for v in table[view][sc].values() if v is not None] or [1.0])
    for ax, view in zip(axes[:, 0], views):
        for i, method in enumerate(methods):
            values = [table[view][s].get(method) for s in scenes]
            xs = [k + (i - len(methods) / 2 + 0.5) * width for k in range(len(scenes))]
            ax.bar(xs, [np.nan if v is None else v for v in values], width=width, color=cmap(i % 20), label=method)
        ax.set_xticks(range(len(scenes)))
        ax.set_xticklabels(scenes, fontsize=8)
        ax.set_ylabel("bad-2 [%]")
        ax.set_ylim(0, top * 1.05)
        name = labels.get(view, view)
        ax.set_title(f"{title + ': ' if title else ''}bad-2 per scene, view {name} ({what.get(view, view)})", fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    fig.tight_layout(rect=(0, 0.06, 1, 1))
    handles, names = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, names, fontsize=7, ncol=min(8, max(1, len(methods))), loc="lower center")
    _save(fig, path, dpi)
    plt.close(fig)


def figure_speed(path: Path, rows: Sequence[Mapping[str, Any]], inputs: Sequence[str], *, dpi: int = 90) -> None:
    """Median time per method (min-max whiskers) for each chosen speed input, one bar per thread count."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    inputs = [i for i in inputs if any(r["input"] == i for r in rows)]
    if not inputs:
        return
    fig, axes = plt.subplots(1, len(inputs), figsize=(6.0 * len(inputs), 0.5 + 0.42 * len({r["method"] for r in rows}) * 1.3), squeeze=False)
    cmap = plt.get_cmap("tab10")
    for ax, name in zip(axes[0], inputs):
        sel = [r for r in rows if r["input"] == name and r.get("median_ms") is not None]
        methods = list(dict.fromkeys(r["method"] for r in sel))
        threads = sorted({r["threads"] for r in sel})
        height = 0.8 / max(1, len(threads))
        for j, t in enumerate(threads):
            ys, med, lo, hi = [], [], [], []
            for i, m in enumerate(methods):
                hit = [r for r in sel if r["method"] == m and r["threads"] == t]
                if not hit:
                    continue
                r = hit[0]
                ys.append(i + (j - len(threads) / 2 + 0.5) * height)
                med.append(r["median_ms"])
                lo.append(r["median_ms"] - r["min_ms"])
                hi.append(r["max_ms"] - r["median_ms"])
            ax.barh(ys, med, height=height, xerr=[lo, hi], color=cmap(j), label=f"{t} thread{'s' if t > 1 else ''}", capsize=2)
        ax.set_yticks(range(len(methods)))
        ax.set_yticklabels(methods, fontsize=8)
        ax.invert_yaxis()
        times = [r["min_ms"] for r in sel if r["min_ms"] > 0] + [r["max_ms"] for r in sel]
        # a logarithmic axis where the times span more than 30x (a single-threaded peer beside 20 ms matchers), so that
        # the fast methods' bars are not slivers
        wide = bool(times) and max(times) > 30 * min(times)
        if wide:
            ax.set_xscale("log")
        ax.set_xlabel("median ms per pair (whiskers: min-max)" + (", log scale" if wide else ""))
        r0 = sel[0]
        ax.set_title(f"{name}: {r0['width']}x{r0['height']}, {r0['num_disparities']} disparities "
                     "(classical methods: grey pair)", fontsize=10)
        ax.grid(axis="x", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    _save(fig, path, dpi)
    plt.close(fig)
