"""Where the matcher's measured pixels go: per post-matching step, how many it removes and how many of those were wrong.

The matcher's valid view (``DisparityMap.disparity``, the measured pixels) keeps the pixels that survive, in pipeline order,
the left-right check (in the kernels, with uniqueness), the border-reach rule (``border_reach``) and the speckle
filter. Per scene the matcher runs three times with the same parameters: every filter off (the raw winners, which
the filters only ever remove, never change), the kernels' filters only, and the full pipeline (holes not filled).
A step's removed pixels are scored with their raw winner against the ground truth, so "bad-2 of removed" says
whether the step removes mostly wrong pixels (good) or mostly right ones (lost density).

The bound: no filter of these winners, however clever, can do better at density ``t`` (% of ground-truth pixels)
than removing only bad pixels: bad-2 >= (raw bad - (raw density - t)) / t. When that bound is above a target, no
post-processing closes it; the winners themselves (cost, aggregation, penalties) must change. A harder bound, for
any matcher: a pixel that only the left image sees (outside the right image, or hidden there behind a nearer
surface) has no correspondence to measure, so the share of the ground truth seen by both views
(:func:`benchmarks.metrics.visible_in_both`, from dense ground truth) caps the density of correct measurements;
the table gives it, and how many measured pixels are seen by the left view only and how many of those are wrong.

    python -m benchmarks.density [--data DIR] [--scenes NAME ...] [--threads N] [--target FAMILY=DENSITY]
                                 [--set FIELD=VALUE ...] [--compare METHOD ...]

``--compare`` scores benchmark methods (``sc-default``, ``ocv-3way``, ...: their measured pixels, with the
benchmark's settings) on the pixels both views see and on those only the left view sees.

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

__all__ = ["STEPS", "bad2_floor", "compare_table", "family_table", "main", "removal_masks", "seen_rows", "step_rows"]

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
    if params.effective_border_reach > 0:  # columns whose reach is short: the rule the matcher applies
        from stereo_classic.matching.border import column_reach, short_reach

        border[:, short_reach(column_reach(raw.shape[1], params), params)] = True
    removed = {"lr+uniqueness": has & ~checked, "border": checked & border, "speckle": checked & ~border & ~kept}
    return raw, removed, kept


def _pct(num: np.ndarray, den: np.ndarray | int) -> float:
    """100 * (pixels of ``num``) / ``den`` (a count, or the pixels of a mask); NaN when ``den`` is 0."""
    total = den if isinstance(den, int) else int(den.sum())
    return 100.0 * int(num.sum()) / total if total else float("nan")


def _mean(rows: Sequence[dict[str, float]], key: str) -> float:
    """Mean of ``key`` over the scene rows that have it (not NaN); NaN when none does."""
    values = [r[key] for r in rows if not np.isnan(r[key])]
    return float(np.mean(values)) if values else float("nan")


def step_rows(raw: np.ndarray, removed: dict[str, np.ndarray], kept: np.ndarray, gt: np.ndarray, *,
              fill_holes: bool = True) -> dict[str, float]:
    """Percentages of one scene: ``raw_density`` / ``raw_bad2`` (every winner kept), ``density`` / ``bad2`` (the
    measured pixels), ``dense_bad2`` (the benchmark's dense view of the matcher's output: the measured pixels,
    filled by ``stereo_classic``'s ``fill_holes`` when ``fill_holes``), and per step ``<step>_removed`` (% of
    ground-truth pixels) and ``<step>_bad2`` (% of those removed that were wrong by more than 2 px; NaN when it
    removed none); ``visible`` (% of the ground-truth pixels seen by both views,
    :func:`benchmarks.metrics.visible_in_both`: the most a matcher can measure by matching), ``hidden_measured``
    (% of them measured although only the left view sees them) and ``hidden_bad2`` (how many of those are wrong).
    Ground truth: NaN where there is none."""
    from benchmarks.metrics import error_metrics
    from stereo_classic.matching.postprocess import fill_holes as fill

    known = np.isfinite(gt)
    n = max(1, int(known.sum()))
    with np.errstate(invalid="ignore"):
        bad = np.abs(raw - gt) > _BAD  # False where either is unknown
    has = np.isfinite(raw) & known

    out = {"raw_density": _pct(has, n), "raw_bad2": _pct(bad & has, has),
           "density": _pct(kept & known, n), "bad2": _pct(bad & kept & known, kept & known)}
    measured = np.where(kept, raw, np.nan).astype(np.float32)
    seen = seen_rows(measured, gt)
    out.update(visible=seen["visible"], hidden_measured=seen["hidden_measured"], hidden_bad2=seen["hidden_bad2"])
    out["dense_bad2"] = float(error_metrics(fill(measured) if fill_holes else measured, gt)["dense"]["bad2"] or 0.0)
    for step in STEPS:
        mask = removed[step] & known
        out[f"{step}_removed"] = _pct(mask, n)
        out[f"{step}_bad2"] = _pct(bad & mask, mask)
    return out


def seen_rows(measured: np.ndarray, gt: np.ndarray) -> dict[str, float]:
    """Percentages of one method's measured pixels (NaN elsewhere) on one scene, split by what the views see
    (:func:`benchmarks.metrics.visible_in_both`): ``visible`` (% of the ground-truth pixels both views see),
    ``density`` (% of the ground-truth pixels measured),
    ``seen_share`` (% of the pixels both views see that are measured), ``seen_bad2`` (bad-2 there),
    ``hidden_measured`` (% of the ground truth measured although only the left view sees it), ``hidden_bad2``
    (bad-2 of those; NaN when none) and ``bad2`` (bad-2 of every measured pixel)."""
    from benchmarks.metrics import visible_in_both

    known = np.isfinite(gt)
    seen = visible_in_both(gt) & known
    has = np.isfinite(measured) & known
    with np.errstate(invalid="ignore"):
        bad = has & (np.abs(measured - gt) > _BAD)
    return {"visible": _pct(seen, known), "density": _pct(has, known), "seen_share": _pct(has & seen, seen),
            "seen_bad2": _pct(bad & seen, has & seen), "hidden_measured": _pct(has & ~seen, known),
            "hidden_bad2": _pct(bad & ~seen, has & ~seen), "bad2": _pct(bad, has)}


def compare_table(rows: dict[str, Sequence[dict[str, float]]]) -> list[str]:
    """Markdown lines: per method (name -> its :func:`seen_rows` per scene) the means over the scenes."""
    header = ("| method | measured (% of GT) | valid bad-2 | measured of what both views see % | bad-2 there | "
              "measured, seen by the left view only (% of GT) | bad-2 of those |")
    lines = [header, "|---|---|---|---|---|---|---|"]
    for name, values in rows.items():
        lines.append(f"| {name} | {_mean(values, 'density'):.1f} | {_mean(values, 'bad2'):.2f} | "
                     f"{_mean(values, 'seen_share'):.1f} | {_mean(values, 'seen_bad2'):.2f} | "
                     f"{_mean(values, 'hidden_measured'):.2f} | {_mean(values, 'hidden_bad2'):.1f} |")
    return lines


def _compare(scene: BenchScene, methods: Sequence[Any], threads: int) -> dict[str, dict[str, float]]:
    from benchmarks.methods import Setup, output_views

    setup = Setup(num_disparities=disparity_range(scene), block_size=5, threads=threads)
    out = {}
    for method in methods:
        _, measured = output_views(method.prepare(setup)(scene.left, scene.right), scene.gt_disparity.shape)
        out[method.name] = seen_rows(measured, scene.gt_disparity)
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
        return _mean(rows, key)

    lines = ["| step | removed (% of GT px) | bad-2 of the removed % |", "|---|---|---|"]
    lines.append(f"| (raw winners, nothing removed) | density {mean('raw_density'):.1f} | bad-2 {mean('raw_bad2'):.2f} |")
    for step in STEPS:
        lines.append(f"| {step} | {mean(step + '_removed'):.2f} | {mean(step + '_bad2'):.1f} |")
    lines.append(f"| = measured pixels | density {mean('density'):.1f} | valid bad-2 {mean('bad2'):.2f} |")
    lines.append(f"| of them seen by the left view only (no correspondence) | {mean('hidden_measured'):.2f} | "
                 f"{mean('hidden_bad2'):.1f} |")
    lines.append(f"| ground truth seen by both views (the most matching can measure) | density "
                 f"{mean('visible'):.1f} | |")
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
    parser.add_argument("--compare", nargs="+", default=[], metavar="METHOD",
                        help="also score these benchmark methods (e.g. sc-default ocv-3way) on the pixels both views "
                             "see and on those only the left one sees")
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
    try:
        from benchmarks.methods import default_methods

        compared = default_methods(args.compare) if args.compare else []
    except ValueError as exc:
        print(f"error: --compare: {exc}", file=sys.stderr)
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
    per_method: dict[str, dict[str, list[dict[str, float]]]] = {}
    for scene in scenes:
        row = step_rows(*removal_masks(scene, **{"threads": args.threads, **settings}), scene.gt_disparity,
                        fill_holes=bool(settings.get("fill_holes", True)))
        log.info("%s: %s", scene.name, ", ".join(f"{k} {v:.2f}" for k, v in row.items()))
        per_family.setdefault(scene.family, []).append(row)
        for name, seen in _compare(scene, compared, args.threads).items():
            per_method.setdefault(scene.family, {}).setdefault(name, []).append(seen)
    for family in FAMILIES:
        if family in per_family:
            rows = per_family[family]
            what = ", ".join(f"{k}={v!r}" for k, v in settings.items()) or "matcher defaults"
            print(f"\n*{family}: mean over {len(rows)} scene(s), {what}, pipeline order*\n")
            print("\n".join(family_table(rows, targets.get(family))))
            if family in per_method:
                print(f"\n*{family}: the methods' measured pixels by what the views see (benchmark settings)*\n")
                print("\n".join(compare_table(per_method[family])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
