"""``python -m stereo_classic disparity LEFT RIGHT -o out.pfm``: disparity of one rectified pair.

Writes the left-view disparity as PFM (float32 pixels, NaN where unknown) and a TURBO-colourised
PNG beside it (unknown pixels black), and prints the valid fraction on stdout and a timing table on stderr
(as ``run``: data on stdout, timings with the logs).
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any

from stereo_classic import io
from stereo_classic.checks import FrameChecker
from stereo_classic.cli.errors import UsageError
from stereo_classic.cli.options import (
    CLI_NUM_DISPARITIES,
    add_options,
    option_names,
    read_options,
)
from stereo_classic.cli.paths import check_output_file
from stereo_classic.matching import (
    DisparityMap,
    SGMParams,
    compute_disparity,
    parse_bytes,
)
from stereo_classic.outputs import colorize, write_all_or_nothing

__all__ = ["add_parser", "func"]

log = logging.getLogger("stereo_classic.disparity")


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register the ``disparity`` sub-command."""
    defaults = SGMParams(num_disparities=CLI_NUM_DISPARITIES)  # as `run` (the library's default is 64)
    parser = subparsers.add_parser(
        "disparity",
        help="disparity map of a rectified stereo pair (PFM + colourised PNG)",
        description="Semi-global matching of a rectified stereo pair. Writes the left-view disparity "
                    "(float32 pixels, d = x_left - x_right, unknown = NaN) as PFM and a colourised PNG beside it.",
    )
    parser.add_argument("left", metavar="LEFT", help="rectified left image")
    parser.add_argument("right", metavar="RIGHT", help="rectified right image")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.pfm", help="disparity output (.pfm)")
    parser.add_argument("--png", metavar="PATH", default=None,
                        help="colourised disparity PNG (default: OUT with the suffix .png)")
    parser.add_argument("--no-png", action="store_true", help="do not write the colourised PNG")
    group = parser.add_argument_group("matcher parameters (docs/matching.md#parameters)")
    add_options(group, SGMParams, defaults=defaults)
    group.add_argument("--threads", type=int, default=defaults.threads, metavar="N",
                       help="worker threads for the kernels (default: every CPU this process may use; the "
                            "disparity is the same for any count)")
    group.add_argument("--memory-limit", default=None, metavar="BYTES",
                       help="refuse pairs needing more memory, e.g. 4G (default: $STEREO_CLASSIC_MEMORY_LIMIT or "
                            "half the RAM)")
    parser.set_defaults(func=func)
    return parser


def _params_from_args(args: argparse.Namespace) -> SGMParams:
    fields = read_options(args, SGMParams)
    fields["threads"] = args.threads
    try:
        if args.memory_limit is not None:
            fields["memory_limit"] = parse_bytes(args.memory_limit, name="--memory-limit")
        return SGMParams(**fields)
    except ValueError as exc:
        raise UsageError(_option_names(str(exc))) from None


def _option_names(message: str) -> str:
    """Name the command-line option in a message that names an SGMParams field."""
    return option_names(message, SGMParams).replace("`threads`", "--threads")


def _outputs(args: argparse.Namespace) -> tuple[Path, Path | None]:
    out = Path(args.output)
    if out.suffix.lower() != ".pfm":
        raise UsageError(f"-o/--output must name a .pfm file, got {str(out)!r}")
    if args.no_png:
        if args.png is not None:
            raise UsageError("--png and --no-png contradict each other")
        return check_output_file(out, "-o/--output"), None
    png = Path(args.png) if args.png is not None else out.with_suffix(".png")
    if png.suffix.lower() != ".png":
        raise UsageError(f"--png must name a .png file, got {str(png)!r}")
    if png.resolve() == out.resolve():
        raise UsageError("--png must differ from -o/--output")
    return check_output_file(out, "-o/--output"), check_output_file(png, "--png")


def func(args: argparse.Namespace) -> int:
    """Run the sub-command; returns the exit code."""
    params = _params_from_args(args)
    out, png = _outputs(args)
    left = io.read_image(args.left)
    right = io.read_image(args.right)
    log.info("matching %s and %s (%d x %d px), disparities %d..%d, cost %s",
             args.left, args.right, left.shape[1], left.shape[0], params.min_disparity, params.max_disparity,
             params.cost)
    dmap = compute_disparity(left, right, params)
    checker = FrameChecker(params)
    for warning in (checker.check_pair(left, right, dmap), checker.range_warning(left, right, dmap)):
        if warning is not None:  # the map is still written: it is what the images give, but say it is wrong
            log.warning("warning: %s", warning.message)
    checker.close()
    colour = None
    if png is not None:
        colour = colorize(dmap.disparity, vmin=params.min_disparity, vmax=params.max_disparity)
    # Each file is written atomically; on a failure the other one is removed again, so no lone PFM or PNG.
    jobs = [(out, lambda path: io.write_pfm(path, dmap.disparity))]
    if png is not None:
        jobs.append((png, lambda path: io.write_image(path, colour)))
    write_all_or_nothing(jobs)
    log.info("wrote %s%s", out, f" and {png}" if png is not None else "")
    _print_summary(dmap, sys.stdout, sys.stderr)
    return 0


def _print_summary(dmap: DisparityMap, stream: Any, timings: Any) -> None:
    v = dmap.validity
    measured = v["valid"] - (v.get("filled") or 0)  # the files hold these; the filled ones are not written
    print(f"valid pixels: {measured} of {v['pixels']} ({100.0 * dmap.valid_fraction:.1f} %)"
          + (f", {v['filled']} more filled (not written)" if v.get("filled") else ""), file=stream)
    print("stage         ms", file=timings)
    for stage, ms in dmap.timings_ms.items():
        print(f"{stage:<12}{ms:>8.1f}", file=timings)
