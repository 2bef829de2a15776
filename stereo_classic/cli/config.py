"""``--config file.toml`` for ``python -m stereo_classic run``: file values merged with flags.

Precedence, lowest first: built-in defaults, the TOML file, flags given on the command line. Top-level
keys are the run options (the long flag names with ``_`` for ``-``); the ``[matcher]`` table holds any
``SGMParams`` field. ``--dump-config`` prints the merged result as TOML, which ``--config`` reads back.

Example::

    model = "yolox_nano"
    conf = 0.35
    classes = ["car", "person"]
    depth_range = [0.5, 60.0]
    seed = 0

    [matcher]
    num_disparities = 128
    cost = "census"
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from stereo_classic.cli.options import option_fields
from stereo_classic.fusion import FusionParams
from stereo_classic.matching import SGMParams
from stereo_classic.outputs import DEFAULT_SAVE

__all__ = ["RUN_DEFAULTS", "FUSION_OPTIONS", "ConfigError", "load_config", "merge_config", "dump_config"]


def _kind(value: Any) -> str:
    """How a value of this type is checked in TOML and on the command line."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, (tuple, list)):
        return "range" if len(value) == 2 and all(isinstance(v, float) for v in value) else "list[str]"
    return {int: "int", float: "float", str: "str"}[type(value)]


def _run_defaults() -> dict[str, tuple[Any, str]]:
    """The run options in ``--dump-config`` order; the fusion ones come from ``FusionParams``."""
    fusion = FusionParams()
    fusion_options = {f.name: getattr(fusion, f.name) for f in option_fields(FusionParams)}
    table: dict[str, Any] = {
        "output": "stereo_out",
        "save": list(DEFAULT_SAVE),
        "ply": False,
        "model": "yolox_nano",
        "conf": 0.3,
        "iou": 0.45,
        "classes": [],
        **{k: (list(v) if isinstance(v, tuple) else v) for k, v in fusion_options.items()},
        "seed": 0,
        "threads": 0,
        "scale": 1.0,
        "max_frames": 0,
        "concurrent": False,
        "on_error": "stop",
        "executor": "serial",
        "scheduler": "",
    }
    return {k: (v, "list[str]" if k in ("save", "classes") else _kind(v)) for k, v in table.items()}


#: Run options with their defaults and kinds (``kind`` decides how TOML and flag values are checked).
RUN_DEFAULTS: dict[str, tuple[Any, str]] = _run_defaults()

#: The run options that are ``FusionParams`` fields.
FUSION_OPTIONS: tuple[str, ...] = tuple(f.name for f in option_fields(FusionParams))


class ConfigError(ValueError):
    """A config file that cannot be used; the message names the file and the key."""


def _check(key: str, value: Any, kind: str, where: str) -> Any:
    def fail(expected: str) -> None:
        raise ConfigError(f"{where}: `{key}` must be {expected}, got {value!r}")

    if kind == "str":
        if not isinstance(value, str):
            fail("a string")
        return value
    if kind == "bool":
        if not isinstance(value, bool):
            fail("true or false")
        return value
    if kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            fail("an integer")
        return value
    if kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            fail("a finite number")
        return float(value)
    if kind == "list[str]":
        if isinstance(value, str):
            value = [v.strip() for v in value.split(",") if v.strip()]
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            fail("a list of strings")
        return list(value)
    if kind == "range":
        if (not isinstance(value, (list, tuple)) or len(value) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
            fail("two numbers [near, far] in metres")
        return [float(value[0]), float(value[1])]
    raise AssertionError(kind)  # pragma: no cover - table above is fixed


def _matcher_fields() -> dict[str, Any]:
    return {f.name: f for f in dataclasses.fields(SGMParams)}


def load_config(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read and check a TOML config file; returns ``{run options..., "matcher": {...}}``.

    Raises
    ------
    ConfigError
        Missing or unreadable file, TOML syntax error, unknown key, or a value of the wrong type.
    """
    p = Path(path)
    if not p.is_file():
        raise ConfigError(f"config file not found: {p}")
    try:
        with p.open("rb") as f:
            raw = tomllib.load(f)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: cannot read: {exc}") from None
    out: dict[str, Any] = {}
    fields = _matcher_fields()
    for key, value in raw.items():
        if key == "matcher":
            if not isinstance(value, dict):
                raise ConfigError(f"{p}: `matcher` must be a table ([matcher]), got {value!r}")
            unknown = sorted(set(value) - set(fields))
            if unknown:
                raise ConfigError(f"{p}: unknown [matcher] key {unknown[0]!r}; expected some of: {', '.join(fields)}")
            out["matcher"] = {k: (tuple(v) if isinstance(v, list) else v) for k, v in value.items()}
            continue
        if key not in RUN_DEFAULTS:
            raise ConfigError(f"{p}: unknown key {key!r}; expected some of: {', '.join(RUN_DEFAULTS)}, [matcher]")
        out[key] = _check(key, value, RUN_DEFAULTS[key][1], str(p))
    return out


def merge_config(file_config: Mapping[str, Any] | None, flags: Mapping[str, Any],
                 matcher_flags: Mapping[str, Any]) -> dict[str, Any]:
    """Defaults < file < flags. ``flags`` / ``matcher_flags`` hold only options given on the command line
    (``None`` values are ignored). Returns every run option plus ``"matcher"`` (only the fields set)."""
    merged = {k: (list(v) if isinstance(v, list) else v) for k, (v, _) in RUN_DEFAULTS.items()}
    file_config = dict(file_config or {})
    matcher = dict(file_config.pop("matcher", {}) or {})
    merged.update(file_config)
    for key, value in flags.items():
        if value is not None:
            merged[key] = _check(key, value, RUN_DEFAULTS[key][1], "command line")
    for key, value in matcher_flags.items():
        if value is not None:
            matcher[key] = value
    merged["matcher"] = matcher
    return merged


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        return repr(value) if math.isfinite(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    raise ConfigError(f"cannot write {value!r} as TOML")


def dump_config(config: Mapping[str, Any]) -> str:
    """The merged config as TOML text (``None`` values are left out: TOML has no null)."""
    lines = ["# python -m stereo_classic run --config this.toml"]
    for key in RUN_DEFAULTS:
        if config.get(key) is not None:
            lines.append(f"{key} = {_toml_value(config[key])}")
    matcher = {k: v for k, v in dict(config.get("matcher") or {}).items() if v is not None}
    lines.append("")
    lines.append("[matcher]")
    for key, value in matcher.items():
        lines.append(f"{key} = {_toml_value(value)}")
    return "\n".join(lines) + "\n"
