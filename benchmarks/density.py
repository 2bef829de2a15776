"""Where the matcher's measured pixels go: per post-matching step, how many it removes and how many of those were wrong.

The matcher's valid view (``DisparityMap.measured_disparity``) keeps the pixels that survive, in pipeline order,
the left-right check (in the kernels, with uniqueness), the border-reach rule (``border_reach``) and the speckle
filter. Per scene the matcher runs three times with the same parameters: every filter off (the raw winners, which
the filters only ever remove, never change), the kernels' filters only, and the full pipeline (holes not filled).
A step's removed pixels are scored with their raw winner against the ground truth, so "bad-2 of removed" says
whether the step removes mostly wrong pixels (good) or mostly right ones (lost density).

The bound: no filter of these winners, however clever, can do better at density ``t`` (% of ground-truth pixels)
than removing only bad pixels: bad-2 >= (raw bad - (raw density - t)) / t. When that bound is above a target, no
post-processing closes it; the winners themselves (cost, aggregation, penalties) must change.

    python -m benchmarks.density [--data DIR] [--scenes NAME ...] [--threads N] [--target FAMILY=DENSITY]
                                 [--set FIELD=VALUE ...]

Percentages are per scene, then averaged over the scenes of a family (as the benchmark's report does), with
the benchmark's own scene loader and disparity range. Pixels without ground truth never count.
"""

from __future__ import annotations

import argparse
import ast
import logging
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks.scenes import FAMILIES, BenchScene, default_data_dir, disparity_range, load_scenes

__all__ = ["STEPS", "bad2_floor", "family_table", "main", "removal_masks", "step_rows"]

log = logging.getLogger("benchmarks")

#: Pipeline steps in order: the kernels' checks (LR and uniqueness), the border-reach rule, the speckle filter.
STEPS: tuple[str, ...] = ("lr+uniqueness", "border", "speckle")
_BAD = 2.0


def removal_masks(scene: BenchScene, **overrides: Any) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """``(raw, removed, kept)`` for one scene: the raw winners ((H, W) float32, NaN where no candidate), per step
    of :data:`STEPS` the (H, W) bool mask of the pixels it removes, and the mask of the measured pixels left.

    ``overrides`` are ``SGMParams`` fields (the disparity range is the benchmark's, block size 5, one thread
    unless ``threads`` is given).
    """
    import stereo_classic as sc

    params = sc.SGMParams(num_disparities=disparity_range(scene), block_size=5, threads=1).replace(**overrides)
    run = lambda **o: sc.compute_disparity(scene.left, scene.right, params.replace(fill_holes=False, **o))  # noqa: E731
    raw = run(lr_check=None, uniqueness=0.0, border_reach=0.0, speckle_size=0).disparity
    checked = np.isfinite(run(border_reach=0.0, speckle_size=0).disparity)
    kept = np.isfinite(run().disparity)
    has = np.isfinite(raw)
    border = np.zeros_like(has)
    if params.border_reach > 0:  # columns whose reach is short: the rule the matcher applies
        from stereo_classic.matching.matcher import _reach, _short_reach

        border[:, _short_reach(_reach(raw.shape[1], params), params)] = True
    removed = {"lr+uniqueness": has & ~checked, "border": checked & border, "speckle": checked & ~border & ~kept}
    return raw, removed, kept


def step_rows(raw: np.ndarray, removed: dict[str, np.ndarray], kept: np.ndarray, gt: np.ndarray, *,
              fill_holes: bool = True) -> dict[str, float]:
    """Percentages of one scene: ``raw_density`` / ``raw_bad2`` (every winner kept), ``density`` / ``bad2`` (the
    measured pixels), ``dense_bad2`` (the benchmark's dense view of the matcher's output: the measured pixels,
    filled by ``stereo_classic``'s ``fill_holes`` when ``fill_holes``), and per step ``<step>_removed`` (% of
    ground-truth pixels) and ``<step>_bad2`` (% of those removed that were wrong by more than 2 px; NaN when it
    removed none). Ground truth: NaN where there is none."""
    from benchmarks.metrics import error_metrics
    from stereo_classic.matching.postprocess import fill_holes as fill

    known = np.isfinite(gt)
    n = max(1, int(known.sum()))
    with np.errstate(invalid="ignore"):
        bad = np.abs(raw - gt) > _BAD  # False where either is unknown
    has = np.isfinite(raw) & known

    def pct(num: np.ndarray, den: np.ndarray | int) -> float:
        total = den if isinstance(den, int) else int(den.sum())
        return 100.0 * int(num.sum()) / total if total else float("nan")

    out = {"raw_density": pct(has, n), "raw_bad2": pct(bad & has, has),
           "density": pct(kept & known, n), "bad2": pct(bad & kept & known, kept & known)}
    measured = np.where(kept, raw, np.nan).astype(np.float32)
    out["dense_bad2"] = float(error_metrics(fill(measured) if fill_holes else measured, gt)["dense"]["bad2"] or 0.0)
    for step in STEPS:
        mask = removed[step] & known
        out[f"{step}_removed"] = pct(mask, n)
        out[f"{step}_bad2"] = pct(bad & mask, mask)
    return out


def bad2_floor(raw_bad2: float, raw_density: float, density: float) -> float:
    """Lowest valid-view bad-2 (%) that any filter of the raw winners reaches at ``density`` (% of ground-truth
    pixels): it removes ``raw_density - density`` points, at best all of them bad.

    >>> round(bad2_floor(30.0, 100.0, 80.0), 2)  # 30 bad of 100; remove 20, all bad: 10 of 80 left
    12.5
    >>> bad2_floor(10.0, 100.0, 50.0)
    0.0
    """
    if not 0 < density <= raw_density:
        raise ValueError(f"`density` must be in (0, raw_density={raw_density}], got {density!r}")
    bad_points = raw_bad2 * raw_density / 100.0
    return 100.0 * max(0.0, bad_points - (raw_density - density)) / density


def family_table(rows: Sequence[dict[str, float]], target_density: float | None = None) -> list[str]:
    """Markdown lines for the scene rows of one family: one line per step, then the measured result (and, with
    ``target_density``, the :func:`bad2_floor` at that density, per scene then averaged)."""
    def mean(key: str) -> float:
        values = [r[key] for r in rows if not np.isnan(r[key])]
        return float(np.mean(values)) if values else float("nan")

    lines = ["| step | removed (% of GT px) | bad-2 of the removed % |", "|---|---|---|"]
    lines.append(f"| (raw winners, nothing removed) | density {mean('raw_density'):.1f} | bad-2 {mean('raw_bad2'):.2f} |")
    for step in STEPS:
        lines.append(f"| {step} | {mean(step + '_removed'):.2f} | {mean(step + '_bad2'):.1f} |")
    lines.append(f"| = measured pixels | density {mean('density'):.1f} | valid bad-2 {mean('bad2'):.2f} |")
    lines.append(f"| output (dense view) | | dense bad-2 {mean('dense_bad2'):.2f} |")
    if target_density is not None:
        floor = np.mean([bad2_floor(r["raw_bad2"], r["raw_density"], min(target_density, r["raw_density"]))
                         for r in rows])
        lines.append(f"| best any filter can do at density {target_density:.1f} | | >= {floor:.2f} |")
    return lines


def _parse_target(text: str) -> tuple[str, float]:
    family, sep, value = text.partition("=")
    try:
        if not sep or family not in FAMILIES:
            raise ValueError
        return family, float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected FAMILY=DENSITY with FAMILY one of {FAMILIES}, got {text!r}") from None


def _parse_setting(text: str) -> tuple[str, Any]:
    field, sep, value = text.partition("=")
    if not sep or not field.isidentifier():
        raise argparse.ArgumentTypeError(f"expected FIELD=VALUE such as p1=56 or lr_mode=opencv, got {text!r}")
    try:
        return field, ast.literal_eval(value)
    except (ValueError, SyntaxError):
        return field, value  # a word: lr_mode=opencv


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.density", description=__doc__.splitlines()[0])
    parser.add_argument("--data", default=None, help="folder of scenes (default: $STEREO_CLASSIC_DATA or ../shared/data)")
    parser.add_argument("--scenes", nargs="+", metavar="NAME", help="only scenes whose name contains one of these")
    parser.add_argument("--threads", type=int, default=1, help="matcher threads (default 1)")
    parser.add_argument("--target", type=_parse_target, action="append", default=[], metavar="FAMILY=DENSITY",
                        help="also print the best valid bad-2 any filter reaches at this density (repeatable)")
    parser.add_argument("--set", type=_parse_setting, action="append", default=[], metavar="FIELD=VALUE",
                        help="an SGMParams field for every run, e.g. p1=56 (repeatable; default: the defaults)")
    parser.add_argument("-v", "--verbose", action="store_true", help="one line per scene on stderr")
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO if args.verbose else logging.WARNING, format="%(message)s")
    if args.threads < 1:
        print(f"error: --threads must be >= 1, got {args.threads}", file=sys.stderr)
        return 2
    settings = dict(args.set)
    try:
        import stereo_classic as sc

        sc.SGMParams(**settings)
    except (TypeError, ValueError) as exc:
        print(f"error: --set: {exc}", file=sys.stderr)
        return 2
    data = Path(args.data) if args.data else default_data_dir()
    try:
        scenes = [s for s in load_scenes(data, args.scenes) if s.gt_disparity is not None]
    except (FileNotFoundError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not scenes:
        print("error: no scene with a ground-truth disparity", file=sys.stderr)
        return 1
    targets = dict(args.target)
    per_family: dict[str, list[dict[str, float]]] = {}
    for scene in scenes:
        row = step_rows(*removal_masks(scene, **{"threads": args.threads, **settings}), scene.gt_disparity,
                        fill_holes=bool(settings.get("fill_holes", True)))
        log.info("%s: %s", scene.name, ", ".join(f"{k} {v:.2f}" for k, v in row.items()))
        per_family.setdefault(scene.family, []).append(row)
    for family in FAMILIES:
        if family in per_family:
            rows = per_family[family]
            what = ", ".join(f"{k}={v!r}" for k, v in settings.items()) or "matcher defaults"
            print(f"\n*{family}: mean over {len(rows)} scene(s), {what}, pipeline order*\n")
            print("\n".join(family_table(rows, targets.get(family))))
    return 0


if __name__ == "__main__":
    sys.exit(main())
