"""``--config file.toml`` for ``python -m stereo_classic run``: file values merged with flags.

Precedence, lowest first: built-in defaults, the TOML file, flags given on the command line. Top-level
keys are the run options (the long flag names with ``_`` for ``-``), the input options included (``left``,
``right``, ``calib``, ``rectify``, ``dataset``, ``video``, ``camera``; paths relative to the current folder,
as on the command line; an input kind given as a flag replaces the file's); the ``[matcher]`` table holds any
``SGMParams`` field. Every value form a flag accepts is accepted as a TOML string too (``census_window =
"9x7"``, ``lr_check = "off"``, ``scale = "0.5"``, ``classes = "car,person"``). ``--dump-config`` prints the
merged result as TOML, which ``--config`` reads back.

Example::

    left = ["left/*.png"]
    right = ["right/*.png"]
    calib = "rig.yaml"
    model = "yolox_nano"
    conf = 0.35
    classes = ["car", "person"]
    depth_range = [0.5, 60.0]
    seed = 0

    [matcher]
    num_disparities = 128
    cost = "census"
    census_window = "9x7"
"""

from __future__ import annotations

import dataclasses
import math
import os
import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from stereo_classic.cli.options import _scalar_type, option_fields
from stereo_classic.fusion import FusionParams
from stereo_classic.matching import SGMParams
from stereo_classic.outputs import DEFAULT_SAVE

__all__ = ["FUSION_OPTIONS", "INPUT_OPTIONS", "RUN_DEFAULTS", "ConfigError", "dump_config", "load_config",
           "merge_config"]

#: The input options (``cli/inputs.py``) a config file may hold, with their kinds; None = not given.
_INPUT_DEFAULTS: dict[str, tuple[Any, str]] = {
    "left": (None, "list[str]"), "right": (None, "list[str]"), "calib": (None, "str"), "rectify": (False, "bool"),
    "dataset": (None, "str"), "video": (None, "str"), "camera": (None, "int"),
    "bag": (None, "str"), "left_topic": (None, "str"), "right_topic": (None, "str"),
    "left_info_topic": (None, "str"), "right_info_topic": (None, "str"), "stamp_tolerance": (None, "float"),
}
#: The input options that choose the kind of input: given as flags, they replace the config file's.
_INPUT_KINDS = ("left", "right", "dataset", "video", "camera", "bag", "left_topic", "right_topic",
                "left_info_topic", "right_info_topic", "stamp_tolerance")


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
        "square_input": False,
        **{k: (list(v) if isinstance(v, tuple) else v) for k, v in fusion_options.items()},
        "seed": 0,
        "threads": 0,
        "scale": 1.0,
        "max_frames": 0,
        "concurrent": False,
        "read_ahead": False,
        "pipeline": True,
        "on_error": "stop",
        "executor": "serial",
        "scheduler": "",
    }
    kinds = {k: (v, "list[str]" if k in ("save", "classes") else _kind(v)) for k, v in table.items()}
    return {**_INPUT_DEFAULTS, **kinds}


#: Run options with their defaults and kinds (``kind`` decides how TOML and flag values are checked).
RUN_DEFAULTS: dict[str, tuple[Any, str]] = _run_defaults()

#: The input options among :data:`RUN_DEFAULTS` (what ``--left``, ``--dataset``, ... set).
INPUT_OPTIONS: tuple[str, ...] = tuple(_INPUT_DEFAULTS)

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
        if isinstance(value, str):  # as on the command line: "3"
            try:
                value = int(value.strip())
            except ValueError:
                fail("an integer")
        if isinstance(value, bool) or not isinstance(value, int):
            fail("an integer")
        return value
    if kind == "float":
        if isinstance(value, str):  # as on the command line: "0.5"
            try:
                value = float(value.strip())
            except ValueError:
                fail("a finite number")
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            fail("a finite number")
        return float(value)
    if kind == "list[str]":
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
            fail("a list of strings")
        # "car,person", ["car", "person"] and ["car,person"] (a flag given as words or with commas) alike
        return [name.strip() for v in value for name in v.split(",") if name.strip()]
    if kind == "range":
        if isinstance(value, str):  # as on the command line: "0.5 60"
            value = value.replace(",", " ").split()
            try:
                value = [float(v) for v in value]
            except ValueError:
                fail("two numbers [near, far] in metres")
        if (not isinstance(value, (list, tuple)) or len(value) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
            fail("two numbers [near, far] in metres")
        return [float(value[0]), float(value[1])]
    raise AssertionError(kind)  # pragma: no cover - table above is fixed


def _matcher_fields() -> dict[str, Any]:
    return {f.name: f for f in dataclasses.fields(SGMParams)}


def _matcher_value(key: str, value: Any, field: dataclasses.Field, where: str) -> Any:
    """A ``[matcher]`` value: TOML lists become tuples; a string is read as its flag reads it ("9x7", "off")."""
    if isinstance(value, list):
        return tuple(value)
    if not isinstance(value, str) or not _is_valued_flag(field):
        return value
    if "parse" in field.metadata:
        convert = field.metadata["parse"]
    else:
        try:
            convert = _scalar_type(field)
        except TypeError:
            return value
        if convert is str:
            return value
    try:
        return convert(value)
    except ValueError as exc:
        raise ConfigError(f"{where}: [matcher] `{key}`: {exc}") from None


def _is_valued_flag(field: dataclasses.Field) -> bool:
    """True for a field that is a command-line flag (it has a help text) and not a switch."""
    return "help" in field.metadata and not isinstance(field.default, bool)


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
            out["matcher"] = {k: _matcher_value(k, v, fields[k], str(p)) for k, v in value.items()}
            try:  # the table's values checked as SGMParams checks them, so that the error names this file
                SGMParams(**out["matcher"])
            except (TypeError, ValueError) as exc:
                raise ConfigError(f"{p}: [matcher] {exc}") from None
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
    if any(flags.get(k) is not None for k in _INPUT_KINDS):  # an input given as flags replaces the file's
        for key in _INPUT_KINDS:
            file_config.pop(key, None)
    merged.update(file_config)
    for key, value in flags.items():
        if value is not None:
            merged[key] = _check(key, value, RUN_DEFAULTS[key][1], "command line")
    for key, value in matcher_flags.items():  # only the flags given; None = "off" (e.g. --lr-check off)
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
    """The merged config as TOML text (run options that are ``None`` are left out: TOML has no null; a matcher
    field set to None, such as ``lr_check``, is written "off", as its flag takes it)."""
    lines = ["# python -m stereo_classic run --config this.toml"]
    for key in RUN_DEFAULTS:
        if config.get(key) is not None:
            lines.append(f"{key} = {_toml_value(config[key])}")
    matcher = dict(config.get("matcher") or {})
    lines.append("")
    lines.append("[matcher]")
    for key, value in matcher.items():  # a field set to None is "off" (lr_check), as its flag writes it
        lines.append(f"{key} = {_toml_value(value) if value is not None else chr(34) + 'off' + chr(34)}")
    return "\n".join(lines) + "\n"
