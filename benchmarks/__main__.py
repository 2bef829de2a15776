"""``python -m benchmarks``: accuracy, speed and memory of this project's matcher against OpenCV, and more.

Examples
--------
python -m benchmarks                                  # ../shared/data when present, else the demo scene
python -m benchmarks --scenes tsukuba --repeat 1 --quick --out /tmp/b
python -m benchmarks --stereo-onnx net.onnx --onnx-option input_size=640x384 --onnx-option mean=0.485,0.456,0.406

Exit codes: 0 success, 1 runtime failure, 2 usage error.
"""

from __future__ import annotations

import argparse
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path

__all__ = ["main", "build_parser"]

log = logging.getLogger("benchmarks")

REPO = Path(__file__).resolve().parents[1]


def _threads(text: str) -> tuple[int, ...]:
    try:
        values = tuple(int(v) for v in text.split(",") if v.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be comma-separated integers like 1,2, got {text!r}") from None
    if not values or any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"must be integers >= 1, got {text!r}")
    return values


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text!r}")
    return value


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m benchmarks",
        description="Reproducible report: this project's matcher vs OpenCV StereoSGBM/StereoBM (and ONNX stereo networks) "
                    "on the same inputs; accuracy, speed, memory, detector latency, pipeline fps, object distances.",
    )
    p.add_argument("--data", type=Path, help="folder of stereo scenes (default: $STEREO_CLASSIC_DATA or ../shared/data, else the built-in demo)")
    p.add_argument("--out", type=Path, default=Path("bench_out"), help="output folder (default ./bench_out)")
    p.add_argument("--scenes", nargs="+", metavar="NAME", help="only scenes whose name contains one of these (case-insensitive)")
    p.add_argument("--methods", nargs="+", metavar="NAME", help="only these built-in methods (e.g. sc-default ocv-hh)")
    p.add_argument("--repeat", type=_positive, default=5, help="timed repetitions per method and input (default 5)")
    p.add_argument("--threads", type=_threads, default=(1, 2), help="thread counts to time, comma-separated (default 1,2)")
    p.add_argument("--block-size", type=int, default=5, help="block size given to every method (default 5)")
    p.add_argument("--sizes", nargs="*", metavar="WxHxD", help="extra speed sizes (default 1242x375x128 640x480x64 1920x1080x256)")
    p.add_argument("--stereo-onnx", nargs="+", type=Path, default=[], metavar="MODEL", help="ONNX stereo network(s) to compare")
    p.add_argument("--onnx-option", action="append", default=[], metavar="KEY=VALUE",
                   help="ONNX stereo preprocessing overriding the model metadata: input_size=WxH, color=rgb|bgr|gray, "
                        "pixel_scale, mean=a,b,c, std=a,b,c, output_scale, pad_multiple (repeatable)")
    p.add_argument("--models", type=Path, help="detector models folder (default: $STEREO_CLASSIC_MODELS or ../shared/models)")
    p.add_argument("--no-memory", action="store_true", help="skip the per-method memory probes")
    p.add_argument("--no-objects", action="store_true", help="skip detector latency, pipeline fps and object distances")
    p.add_argument("--no-figures", action="store_true", help="write no figures")
    p.add_argument("--no-scaling", action="store_true", help="skip the thread-scaling table (matcher and 3WAY on the KITTI pair)")
    p.add_argument("--quick", action="store_true", help="real scenes only (no synthetic sizes), first thread count only, one memory probe")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    verbosity = p.add_mutually_exclusive_group()
    verbosity.add_argument("-v", "--verbose", action="store_true", help="debug logs and full tracebacks")
    verbosity.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    return p


def _default_dir(env: str, sub: str) -> Path | None:
    value = os.environ.get(env)
    path = Path(value) if value else REPO.parent / "shared" / sub
    return path if path.is_dir() else None


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark; returns the exit code (0 ok, 1 runtime failure, 2 usage error)."""
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return int(exc.code or 0)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(levelname)s %(name)s: %(message)s" if args.verbose else "%(message)s"))
    log.handlers[:] = [handler]
    log.propagate = False
    log.setLevel(logging.DEBUG if args.verbose else logging.WARNING if args.quiet else logging.INFO)

    from stereo_classic.cli import UsageError
    from stereo_classic.cli.paths import check_output_dir

    try:  # before any work: an --out that cannot be a folder fails now, not after the benchmark
        check_output_dir(args.out, "--out")
    except UsageError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2

    from benchmarks.run import DEFAULT_SIZES, BenchConfig, run_benchmark
    from benchmarks.scenes import default_data_dir, parse_size
    from benchmarks.stereo_onnx import parse_options

    try:
        sizes = tuple(parse_size(s) for s in args.sizes) if args.sizes is not None else DEFAULT_SIZES
        options: dict[str, str] = {}
        for item in args.onnx_option:
            if "=" not in item:
                raise ValueError(f"`--onnx-option` must be KEY=VALUE, got {item!r}")
            key, value = item.split("=", 1)
            options[key.strip()] = value.strip()
        onnx_options = parse_options(options)
        unknown = [k for k in options if k.strip().lower() not in ("input_size", "size", "color", "pixel_scale", "scale", "mean", "std", "output_scale", "pad_multiple")]
        if unknown:
            raise ValueError(f"`--onnx-option` keys must be input_size, color, pixel_scale, mean, std, output_scale or pad_multiple, got {unknown}")
        if args.methods:
            from benchmarks.methods import default_methods

            default_methods(args.methods)  # unknown names are a usage error, before any work
        data_dir = args.data if args.data is not None else default_data_dir()
        if args.data is None:
            log.info("data: %s", data_dir if data_dir else "built-in demo scene (no ../shared/data, no $STEREO_CLASSIC_DATA)")
        config = BenchConfig(
            data_dir=data_dir, out_dir=args.out, scenes=args.scenes, methods=args.methods, repeat=args.repeat,
            threads=tuple(args.threads), block_size=args.block_size, sizes=sizes, stereo_onnx=list(args.stereo_onnx),
            onnx_options=onnx_options, models_dir=args.models if args.models is not None else _default_dir("STEREO_CLASSIC_MODELS", "models"),
            memory=not args.no_memory, objects=not args.no_objects, figures=not args.no_figures, quick=args.quick,
            progress=False if args.no_progress else None, scaling=not args.no_scaling,
        )
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    def run() -> int:
        from benchmarks.render import write_report

        report, arrays = run_benchmark(config, argv=argv)
        written = write_report(report, arrays, config.out_dir, figures=config.figures)
        log.info("wrote %s", ", ".join(str(p) for p in written))
        return 0

    from stereo_classic.cli import run_guarded

    return run_guarded(run, verbose=bool(args.verbose))


if __name__ == "__main__":
    sys.exit(main())
