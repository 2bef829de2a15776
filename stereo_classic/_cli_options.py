"""The matcher's command-line options, one table for ``disparity`` and ``run``.

Each row: (flag, SGMParams field, argparse keywords, help). ``add_matcher_options`` registers them with
the SGMParams defaults (``disparity``: the value is always set) or with ``None`` (``run``: only the
flags given are merged over the config file); ``matcher_fields`` reads them back; ``option_names``
rewrites a message naming a field (``\\`p2\\```) with its flag (``--p2``).
"""

from __future__ import annotations

import argparse
from typing import Any

__all__ = ["MATCHER_OPTIONS", "add_matcher_options", "matcher_fields", "option_names"]


def census_window(text: str) -> tuple[int, int]:
    """``9x7`` (or ``9,7``) as (width, height)."""
    parts = text.lower().replace(",", "x").split("x")
    try:
        if len(parts) != 2:
            raise ValueError
        return int(parts[0]), int(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT such as 9x7, got {text!r}") from None


def lr_check(text: str) -> float | None:
    """A tolerance in pixels, or ``off`` / ``none`` / ``no`` for no check."""
    if text.lower() in ("off", "none", "no"):
        return None
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number of pixels or 'off', got {text!r}") from None


MATCHER_OPTIONS: tuple[tuple[str, str, dict[str, Any], str], ...] = (
    ("--min-disparity", "min_disparity", {"type": int, "metavar": "PX"},
     "smallest disparity searched, px (may be negative)"),
    ("--num-disparities", "num_disparities", {"type": int, "metavar": "N"},
     "number of disparities searched (any positive integer)"),
    ("--cost", "cost", {"type": str, "metavar": "census|sad"},
     "matching cost: census (robust to exposure differences) or sad (the paper's)"),
    ("--block-size", "block_size", {"type": int, "metavar": "N"}, "odd SAD window side, 1..21 (cost sad)"),
    ("--census-window", "census_window", {"type": census_window, "metavar": "WxH"},
     "census window, odd width x odd height, at most 64 bits (cost census)"),
    ("--p1", "p1", {"type": int, "metavar": "P1"}, "penalty for a 1 px disparity change (default: by cost)"),
    ("--p2", "p2", {"type": int, "metavar": "P2"}, "penalty for larger disparity changes, > p1 (default: by cost)"),
    ("--uniqueness", "uniqueness", {"type": float, "metavar": "PCT"}, "uniqueness ratio in percent, 0 = off"),
    ("--lr-check", "lr_check", {"type": lr_check, "metavar": "PX|off"},
     "largest left-right disparity difference, px, or 'off' (1 for fewer, more reliable pixels)"),
    ("--lr-mode", "lr_mode", {"choices": ("full", "opencv")},
     "left-right check: full (strict) or opencv (StereoSGBM's collision check)"),
    ("--speckle-size", "speckle_size", {"type": int, "metavar": "PIXELS"},
     "remove regions smaller than this many pixels, 0 = off"),
    ("--speckle-range", "speckle_range", {"type": float, "metavar": "PX"},
     "largest disparity step inside one speckle region, px"),
    ("--paths", "paths", {"type": int, "choices": (4, 8)}, "aggregation directions"),
    ("--adaptive-p2", "adaptive_p2", {"action": "store_const", "const": True}, "divide P2 by the intensity gradient"),
    ("--no-subpixel", "subpixel", {"action": "store_const", "const": False}, "integer disparities only"),
    ("--fill-holes", "fill_holes", {"action": "store_const", "const": True},
     "fill unknown pixels from the background side (dense map, filled values are guesses)"),
)


def add_matcher_options(group: Any, *, dest_prefix: str = "", defaults: Any = None,
                        help_overrides: dict[str, str] | None = None) -> None:
    """Add every row of ``MATCHER_OPTIONS`` to ``group``.

    ``defaults``: an SGMParams whose values become the defaults (shown in --help), or None (unset
    options stay None). ``dest_prefix`` is put before each field name to form the argparse ``dest``.
    """
    overrides = dict(help_overrides or {})
    for flag, name, kwargs, text in MATCHER_OPTIONS:
        text = overrides.get(name, text)
        default = getattr(defaults, name) if defaults is not None else None
        if defaults is not None and default is not None and kwargs.get("action") is None:
            text += " (default: %(default)s)"
        group.add_argument(flag, dest=f"{dest_prefix}{name}", default=default, help=text, **kwargs)


def matcher_fields(args: argparse.Namespace, *, dest_prefix: str = "") -> dict[str, Any]:
    """{SGMParams field: value} of every matcher option (None where unset and no default was given)."""
    return {name: getattr(args, f"{dest_prefix}{name}") for _, name, _, _ in MATCHER_OPTIONS}


def option_names(message: str) -> str:
    """Name the command-line flag in a message that names an SGMParams field in backticks."""
    for flag, name, _, _ in MATCHER_OPTIONS:
        message = message.replace(f"`{name}`", flag)
    return message
