"""Command-line entry point: ``python -m stereo_classic <command> ...``.

Each sub-command lives in its own module of this package that defines ``add_parser(subparsers)``
(registering its options and ``set_defaults(func=...)``) and a ``func(args) -> int``. Logs go to
stderr, data to stdout or files. Exit codes: 0 success, 1 runtime failure, 2 usage error.
"""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable, Sequence

from stereo_classic.cli import calibrate, disparity, guide, ros, run
from stereo_classic.cli.errors import UsageError

__all__ = ["main", "console_main", "UsageError", "build_parser", "run_guarded"]

log = logging.getLogger("stereo_classic")

# Sub-command modules, in the order they appear in ``--help``.
_SUBCOMMANDS = (run, guide, disparity, calibrate, ros)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m stereo_classic",
        description="Stereo depth, object detection and per-object distance from a calibrated stereo pair.",
    )
    verbosity = parser.add_mutually_exclusive_group()
    verbosity.add_argument("-v", "--verbose", action="count", default=0, help="more log output (-vv for debug); full tracebacks")
    verbosity.add_argument("-q", "--quiet", action="store_true", help="only warnings and errors")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in _SUBCOMMANDS:
        module.add_parser(subparsers)
    # -v/-q are also accepted after the command (`run -q`); SUPPRESS keeps the global value when absent.
    for sub in subparsers.choices.values():
        group = sub.add_mutually_exclusive_group()
        group.add_argument("-v", "--verbose", action="count", default=argparse.SUPPRESS, help="more log output; full tracebacks")
        group.add_argument("-q", "--quiet", action="store_true", default=argparse.SUPPRESS, help="only warnings and errors")
    return parser


def _configure_logging(verbose: int, quiet: bool) -> None:
    level = logging.WARNING if quiet else (logging.DEBUG if verbose >= 2 else logging.INFO)
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(message)s" if verbose == 0 else "%(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(level)
    # Dask's own INFO lines (scheduler, nanny, worker start/stop: about 50 a run) only with -v
    logging.getLogger("distributed").setLevel(level if verbose else max(level, logging.WARNING))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the process exit code (0 ok, 1 runtime failure, 2 usage error)."""
    parser = build_parser()
    try:
        args = parser.parse_args(list(argv) if argv is not None else None)
    except SystemExit as exc:  # argparse: --help (0) or a usage error (2)
        return int(exc.code or 0)
    _configure_logging(args.verbose, args.quiet)
    if not getattr(args, "func", None):
        parser.print_help(sys.stderr)
        return 2
    return run_guarded(lambda: args.func(args), verbose=bool(args.verbose))


def run_guarded(func: Callable[[], int], *, verbose: bool = False) -> int:
    """Call ``func`` and turn the documented errors into exit codes with a one-line message on stderr.

    ``UsageError`` -> 2, ``KeyboardInterrupt`` -> 130, ``ValueError`` / ``OSError`` / ``RuntimeError`` /
    ``MemoryError`` -> 1; ``verbose`` adds the traceback to the log.
    """
    try:
        return int(func())
    except UsageError as exc:
        if verbose:
            log.exception("usage error")
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except (ValueError, OSError, RuntimeError, MemoryError) as exc:
        if verbose:
            log.exception("failed")
        print(f"error: {exc}", file=sys.stderr)
        return 1


def console_main() -> None:
    sys.exit(main())
