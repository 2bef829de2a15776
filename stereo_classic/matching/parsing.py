"""Text and environment values of the matcher's parameters: byte counts, the memory limit, census windows and
left-right tolerances as the command line and config files write them (``params.SGMParams`` re-exports them)."""

from __future__ import annotations

import math
import os

__all__ = ["MEMORY_LIMIT_ENV", "default_memory_limit", "parse_bytes", "parse_census_window", "parse_lr_check"]

#: Environment variable that sets the default memory limit (bytes, or with a K/M/G/T suffix: "4G").
MEMORY_LIMIT_ENV = "STEREO_CLASSIC_MEMORY_LIMIT"

_SUFFIXES = {"": 1, "B": 1, "K": 1024, "KB": 1024, "KIB": 1024, "M": 1024**2, "MB": 1024**2, "MIB": 1024**2,
             "G": 1024**3, "GB": 1024**3, "GIB": 1024**3, "T": 1024**4, "TB": 1024**4, "TIB": 1024**4}


def parse_bytes(text: str, *, name: str = MEMORY_LIMIT_ENV) -> int:
    """Parse a byte count such as ``"4000000000"``, ``"4G"`` or ``"512 MiB"`` (binary units).

    Raises ``ValueError`` naming ``name`` when the text is not a positive size.
    """
    cleaned = str(text).strip().upper().replace(" ", "")
    number = cleaned.rstrip("KMGTIB")
    suffix = cleaned[len(number):]
    try:
        value = float(number)
    except ValueError:
        value = math.nan
    if suffix not in _SUFFIXES or not math.isfinite(value) or value <= 0:
        raise ValueError(f"`{name}` must be a positive byte count such as 4000000000 or 4G, got {text!r}")
    return int(value * _SUFFIXES[suffix])


def _physical_memory() -> int | None:
    try:
        pages = os.sysconf("SC_PHYS_PAGES")
        page_size = os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, ValueError, OSError):
        return None
    if pages <= 0 or page_size <= 0:
        return None
    return int(pages) * int(page_size)


def default_memory_limit() -> int:
    """The memory limit used when ``SGMParams.memory_limit`` is None, in bytes.

    ``$STEREO_CLASSIC_MEMORY_LIMIT`` when set (bytes or "4G"), else 50 % of physical RAM,
    else (RAM unknown) 4 GiB.
    """
    env = os.environ.get(MEMORY_LIMIT_ENV)
    if env is not None and env.strip():
        return parse_bytes(env)
    physical = _physical_memory()
    return physical // 2 if physical else 4 * 1024**3


def parse_census_window(text: str) -> tuple[int, int]:
    """A census window written ``9x7`` (or ``9,7``) as (width, height); ValueError otherwise.

    >>> parse_census_window("9x7"), parse_census_window("5,5")
    ((9, 7), (5, 5))
    """
    parts = text.lower().replace(",", "x").split("x")
    try:
        if len(parts) != 2:
            raise ValueError
        return int(parts[0]), int(parts[1])
    except ValueError:
        raise ValueError(f"expected WIDTHxHEIGHT such as 9x7, got {text!r}") from None


def parse_lr_check(text: str) -> float | None:
    """A left-right tolerance in pixels, or None for ``off`` / ``none`` / ``no``; ValueError otherwise.

    >>> parse_lr_check("1.5"), parse_lr_check("off")
    (1.5, None)
    """
    if text.lower() in ("off", "none", "no"):
        return None
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"expected a number of pixels or 'off', got {text!r}") from None
