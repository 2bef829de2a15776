"""``python -m stereo_classic disparity LEFT RIGHT -o out.pfm``: disparity of one rectified pair.

Writes the left-view disparity as PFM (float32 pixels, NaN where unknown) and a TURBO-colourised
PNG beside it (unknown pixels black), and prints the valid fraction and a timing table on stdout.
"""

from __future__ import annotations

import argparse
import logging
import sys
from pathlib import Path
from typing import Any

from stereo_classic.cli import UsageError

__all__ = ["add_parser", "func"]

log = logging.getLogger("stereo_classic.disparity")

# (option, SGMParams field, type, help); defaults come from SGMParams so that --help shows them.
_PARAM_OPTIONS: tuple[tuple[str, str, Any, str], ...] = (
    ("--min-disparity", "min_disparity", int, "smallest disparity searched, px (may be negative)"),
    ("--num-disparities", "num_disparities", int, "number of disparities searched (any positive integer)"),
    ("--block-size", "block_size", int, "odd SAD window side, 1..21 (cost sad)"),
    ("--p1", "p1", int, "penalty for a 1 px disparity change (default: by cost)"),
    ("--p2", "p2", int, "penalty for larger disparity changes, > p1 (default: by cost)"),
    ("--uniqueness", "uniqueness", float, "uniqueness ratio in percent, 0 = off"),
    ("--speckle-size", "speckle_size", int, "remove regions smaller than this many pixels, 0 = off"),
    ("--speckle-range", "speckle_range", float, "largest disparity step inside one speckle region, px"),
    ("--threads", "threads", int, "worker threads for the kernels (default: one per CPU; the kernels use at most 2)"),
)


_METAVARS = {"min_disparity": "PX", "num_disparities": "N", "block_size": "N", "p1": "P1", "p2": "P2",
             "uniqueness": "PCT", "speckle_size": "PIXELS", "speckle_range": "PX", "threads": "N"}


def _census_window(text: str) -> tuple[int, int]:
    parts = text.lower().replace(",", "x").split("x")
    try:
        if len(parts) != 2:
            raise ValueError
        return int(parts[0]), int(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 9x7, got {text!r}") from None


def _lr_check(text: str) -> float | None:
    if text.lower() in ("off", "none", "no"):
        return None
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of pixels or 'off', got {text!r}") from None


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register the ``disparity`` sub-command."""
    from stereo_classic.params import SGMParams

    defaults = SGMParams()
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
    group = parser.add_argument_group("matcher parameters (see the README's parameter table)")
    group.add_argument("--cost", choices=("census", "sad"), default=defaults.cost,
                       help="matching cost: census (robust to exposure differences) or sad (the paper's); "
                            "default %(default)s")
    for option, name, kind, text in _PARAM_OPTIONS:
        default = getattr(defaults, name)
        suffix = " (default: %(default)s)" if default is not None else ""
        group.add_argument(option, dest=name, type=kind, default=default, metavar=_METAVARS[name],
                           help=text + suffix)
    group.add_argument("--census-window", type=_census_window, default=defaults.census_window,
                       metavar="WxH", help="census window, odd width x odd height, at most 64 bits (default: 9x7)")
    group.add_argument("--lr-check", type=_lr_check, default=defaults.lr_check, metavar="PX|off",
                       help="largest left-right disparity difference, px, or 'off' (default: off; 1 for fewer, more "
                            "reliable pixels)")
    group.add_argument("--lr-mode", choices=("full", "opencv"), default=defaults.lr_mode,
                       help="left-right check: full (strict) or opencv (StereoSGBM's collision check) "
                            "(default: %(default)s)")
    group.add_argument("--paths", type=int, choices=(4, 8), default=defaults.paths,
                       help="aggregation directions (default: %(default)s)")
    group.add_argument("--adaptive-p2", action="store_true", help="divide P2 by the intensity gradient")
    group.add_argument("--no-subpixel", dest="subpixel", action="store_false", help="integer disparities only")
    group.add_argument("--fill-holes", action="store_true",
                       help="fill unknown pixels from the background side (dense map, filled values are guesses)")
    group.add_argument("--memory-limit", default=None, metavar="BYTES",
                       help="refuse pairs needing more memory, e.g. 4G (default: $STEREO_CLASSIC_MEMORY_LIMIT or "
                            "half the RAM)")
    parser.set_defaults(func=func)
    return parser


def _params_from_args(args: argparse.Namespace) -> Any:
    from stereo_classic.params import SGMParams, parse_bytes

    fields = {name: getattr(args, name) for _, name, _, _ in _PARAM_OPTIONS}
    fields.update(cost=args.cost, census_window=args.census_window, lr_check=args.lr_check, lr_mode=args.lr_mode,
                  paths=args.paths,
                  adaptive_p2=args.adaptive_p2, subpixel=args.subpixel, fill_holes=args.fill_holes)
    try:
        if args.memory_limit is not None:
            fields["memory_limit"] = parse_bytes(args.memory_limit, name="--memory-limit")
        return SGMParams(**fields)
    except ValueError as exc:
        raise UsageError(_option_names(str(exc))) from None


def _option_names(message: str) -> str:
    """Name the command-line option in a message that names an SGMParams field."""
    for option, name, _, _ in _PARAM_OPTIONS + (("--census-window", "census_window", None, ""),
                                                  ("--lr-check", "lr_check", None, ""),
                                                  ("--cost", "cost", None, "")):
        message = message.replace(f"`{name}`", f"{option}")
    return message


def _outputs(args: argparse.Namespace) -> tuple[Path, Path | None]:
    out = Path(args.output)
    if out.suffix.lower() != ".pfm":
        raise UsageError(f"-o/--output must name a .pfm file, got {str(out)!r}")
    if args.no_png:
        if args.png is not None:
            raise UsageError("--png and --no-png contradict each other")
        if not out.parent.is_dir():
            raise UsageError(f"-o/--output: folder {str(out.parent)!r} does not exist")
        return out, None
    png = Path(args.png) if args.png is not None else out.with_suffix(".png")
    if png.suffix.lower() != ".png":
        raise UsageError(f"--png must name a .png file, got {str(png)!r}")
    if png.resolve() == out.resolve():
        raise UsageError("--png must differ from -o/--output")
    for path, option in ((out, "-o/--output"), (png, "--png")):
        if not path.parent.is_dir():
            raise UsageError(f"{option}: folder {str(path.parent)!r} does not exist")
    return out, png


def func(args: argparse.Namespace) -> int:
    """Run the sub-command; returns the exit code."""
    from stereo_classic import io, visualize
    from stereo_classic.matcher import compute_disparity

    params = _params_from_args(args)
    out, png = _outputs(args)
    left = io.read_image(args.left)
    right = io.read_image(args.right)
    log.info("matching %s and %s (%d x %d px), disparities %d..%d, cost %s",
             args.left, args.right, left.shape[1], left.shape[0], params.min_disparity, params.max_disparity,
             params.cost)
    dmap = compute_disparity(left, right, params)
    colour = None
    if png is not None:
        colour = visualize.colorize(dmap.disparity, vmin=params.min_disparity, vmax=params.max_disparity)
    # Each file is written atomically; on a failure the other one is removed again, so no lone PFM or PNG.
    written: list[Path] = []
    try:
        written.append(out)
        io.write_pfm(out, dmap.disparity)
        if colour is not None:
            written.append(png)
            io.write_image(png, colour)
    except BaseException:
        for path in written:
            path.unlink(missing_ok=True)
        raise
    log.info("wrote %s%s", out, f" and {png}" if png is not None else "")
    _print_summary(dmap, sys.stdout)
    return 0


def _print_summary(dmap: Any, stream: Any) -> None:
    v = dmap.validity
    print(f"valid pixels: {v['valid']} of {v['pixels']} ({100.0 * dmap.valid_fraction:.1f} %)"
          + (f", {v['filled']} filled" if v.get("filled") else ""), file=stream)
    print("stage         ms", file=stream)
    for stage, ms in dmap.timings_ms.items():
        print(f"{stage:<12}{ms:>8.1f}", file=stream)
