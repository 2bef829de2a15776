"""The command line, a thin layer over the library: parse, call it, map errors to exit codes.

``python -m stereo_classic run|disparity|calibrate``; :func:`main` is the entry point (``argv`` ->
exit code). Modules: ``main`` (parser, logging, exit codes), ``options`` (flags generated from the
parameter dataclasses), ``config`` (the TOML config of ``run``), one module per sub-command.
"""

from stereo_classic.cli.errors import UsageError
from stereo_classic.cli.main import build_parser, console_main, main, run_guarded

__all__ = ["UsageError", "build_parser", "console_main", "main", "run_guarded"]
