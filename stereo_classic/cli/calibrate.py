"""``python -m stereo_classic calibrate``: stereo calibration from board image pairs -> OpenCV YAML.

Pairs come from two globs (``--left 'cal/left*.png' --right 'cal/right*.png'``, paired in sorted order) or
from a folder holding ``left*``/``right*`` files (paired by the rest of the name: ``left_07.png`` with
``right_07.png``). Prints a short report on stdout and writes the rig atomically.
"""

from __future__ import annotations

import argparse
import glob
import logging
import sys
import time
from pathlib import Path
from typing import Any

import calib
from stereo_classic.cli.errors import UsageError
from stereo_classic.cli.paths import check_output_file

__all__ = ["add_parser", "func", "find_pairs"]

log = logging.getLogger("stereo_classic.calibrate")

_IMAGE_EXTS = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".ppm", ".pgm")


def _board_size(text: str) -> tuple[int, int]:
    parts = text.lower().replace(",", "x").split("x")
    try:
        if len(parts) != 2:
            raise ValueError
        cols, rows = int(parts[0]), int(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected COLSxROWS such as 9x6, got {text!r}") from None
    if cols < 2 or rows < 2:
        raise argparse.ArgumentTypeError(f"board size must be at least 2x2, got {text!r}")
    return cols, rows


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register the ``calibrate`` sub-command."""
    parser = subparsers.add_parser(
        "calibrate",
        help="calibrate a stereo camera from checkerboard/ChArUco image pairs (writes OpenCV YAML)",
        description="Stereo calibration (cv2.calibrateCamera + cv2.stereoCalibrate) from image pairs of a board. "
                    "Writes K1 D1 K2 D2 R T (T in metres), the image size and R1 R2 P1 P2 Q as OpenCV YAML.",
    )
    src = parser.add_argument_group("image pairs (either --folder or --left and --right)")
    src.add_argument("--folder", metavar="DIR", help="folder with left*/right* images, paired by the rest of the name")
    src.add_argument("--left", metavar="GLOB", help="glob of the left images (quote it), paired in sorted order")
    src.add_argument("--right", metavar="GLOB", help="glob of the right images (quote it)")
    board = parser.add_argument_group("board")
    board.add_argument("--board", choices=("checkerboard", "charuco"), default="checkerboard",
                       help="board type (default %(default)s)")
    board.add_argument("--board-size", type=_board_size, required=True, metavar="COLSxROWS",
                       help="checkerboard: inner corners (9x6 for a board of 10x7 squares); charuco: squares")
    board.add_argument("--square", type=_positive_float, required=True, metavar="METRES",
                       help="side of one square in metres (e.g. 0.025)")
    board.add_argument("--marker", type=_positive_float, metavar="METRES", help="charuco: side of a marker in metres")
    board.add_argument("--dictionary", default="DICT_5X5_100", help="charuco: ArUco dictionary (default %(default)s)")
    opts = parser.add_argument_group("calibration")
    opts.add_argument("--min-views", type=int, default=5, metavar="N", help="fewest usable pairs (default %(default)s)")
    opts.add_argument("--fix-k3", action="store_true", help="keep k3 = 0 (little distortion or few views)")
    opts.add_argument("--rational", action="store_true", help="8-coefficient rational distortion model")
    parser.add_argument("-o", "--output", required=True, metavar="RIG.yaml", help="output OpenCV YAML (.yaml/.yml or .xml)")
    parser.set_defaults(func=func)
    return parser


def find_pairs(folder: str | Path) -> list[tuple[Path, Path]]:
    """``left*``/``right*`` image pairs in ``folder``, matched by the rest of the file name, sorted."""
    folder = Path(folder)
    if not folder.is_dir():
        raise UsageError(f"--folder {folder} is not a folder")
    files = [p for p in folder.iterdir() if p.is_file() and p.suffix.lower() in _IMAGE_EXTS]
    lefts = {p.name[4:].lower(): p for p in files if p.name.lower().startswith("left")}
    rights = {p.name[5:].lower(): p for p in files if p.name.lower().startswith("right")}
    if not lefts and not rights:
        raise UsageError(f"--folder {folder} has no left*/right* images ({', '.join(_IMAGE_EXTS)})")
    unmatched = sorted(set(lefts) ^ set(rights))
    if unmatched:
        log.warning("%d image(s) in %s have no partner and are skipped: %s", len(unmatched), folder,
                    ", ".join((lefts.get(k) or rights[k]).name for k in unmatched[:5]))
    return [(lefts[k], rights[k]) for k in sorted(set(lefts) & set(rights))]


def _glob(pattern: str, option: str) -> list[Path]:
    paths = sorted(Path(p) for p in glob.glob(pattern) if Path(p).is_file())
    if not paths:
        raise UsageError(f"{option} {pattern!r} matches no files")
    return paths


def func(args: argparse.Namespace) -> int:
    """Run the ``calibrate`` sub-command."""
    if args.folder and (args.left or args.right):
        raise UsageError("give either --folder or --left/--right, not both")
    output = Path(args.output)
    if output.suffix.lower() not in (".yaml", ".yml", ".xml"):
        raise UsageError(f"--output must end in .yaml, .yml or .xml, got {output.name!r}")
    check_output_file(output, "-o/--output")
    if args.folder:
        pairs = find_pairs(args.folder)
    elif args.left and args.right:
        lefts, rights = _glob(args.left, "--left"), _glob(args.right, "--right")
        if len(lefts) != len(rights):
            raise UsageError(f"--left matches {len(lefts)} files but --right matches {len(rights)}")
        pairs = list(zip(lefts, rights))
    else:
        raise UsageError("give the image pairs: --folder DIR, or --left GLOB and --right GLOB")
    if not pairs:
        raise UsageError("no left/right image pairs found")
    if args.min_views < 3:
        raise UsageError(f"--min-views must be >= 3, got {args.min_views}")

    cols, rows = args.board_size
    try:
        if args.board == "checkerboard":
            board = calib.CheckerBoard(cols, rows, args.square)
        else:
            if args.marker is None:
                raise UsageError("--board charuco needs --marker METRES (side of one ArUco marker)")
            board = calib.CharucoBoard(cols, rows, args.square, args.marker, dictionary=args.dictionary)
    except calib.CalibrationError as exc:
        raise UsageError(str(exc)) from None

    log.info("calibrating from %d pair(s), %s", len(pairs), board.describe())
    start = time.perf_counter()
    rig, report = calib.calibrate_stereo(
        [p[0] for p in pairs], [p[1] for p in pairs], board=board, min_views=args.min_views,
        fix_k3=args.fix_k3, rational_model=args.rational, names=[p[0].name for p in pairs], progress=not args.quiet,
    )
    elapsed = time.perf_counter() - start
    rig.to_opencv_yaml(output)
    out = sys.stdout
    print(report.summary(), file=out)
    print(f"baseline: {rig.baseline_m:.5f} m", file=out)
    print(f"focal length: left {rig.K_left[0, 0]:.2f} px, right {rig.K_right[0, 0]:.2f} px", file=out)
    print(f"time: {elapsed:.2f} s", file=out)
    print(f"wrote {output}", file=out)
    if report.rms_px > 1.0:
        log.warning("RMS reprojection error %.2f px is high: check the board size/square and the worst views", report.rms_px)
    return 0
