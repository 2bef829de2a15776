"""Command-line flags generated from the parameter dataclasses (``SGMParams``, ``FusionParams``).

A field is a flag when its ``dataclasses.field`` metadata has a ``"help"`` text; optional metadata:
``"metavar"``, ``"choices"``, ``"nargs"`` and ``"parse"`` (str -> value, raising ValueError). The flag is
the field name with ``-`` for ``_``; a bool field becomes a switch towards the value that is not its
default (``adaptive_p2=False`` -> ``--adaptive-p2``, ``subpixel=True`` -> ``--no-subpixel``). The types
come from the defaults, so nothing about a parameter is written twice.

Examples
--------
>>> import argparse
>>> from stereo_classic.fusion import FusionParams
>>> parser = argparse.ArgumentParser()
>>> add_options(parser, FusionParams)
>>> args = parser.parse_args(["--box-shrink", "0.1", "--depth-range", "1", "50"])
>>> read_options(args, FusionParams)["depth_range"]
[1.0, 50.0]
>>> flag_of(FusionParams, "box_shrink")
'--box-shrink'
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["CLI_NUM_DISPARITIES", "add_options", "flag_of", "option_fields", "option_names", "read_options"]

#: Disparities searched by the commands (``run`` without a scene range, ``disparity``) unless told otherwise:
#: 128 px reach 3 m on KITTI and 0.26 m on an OAK-D; the library's ``SGMParams`` default (64) stays the cheap one.
CLI_NUM_DISPARITIES = 128


def option_fields(cls: type) -> list[dataclasses.Field]:
    """The fields of dataclass ``cls`` that are command-line flags (those with a "help" text)."""
    return [f for f in dataclasses.fields(cls) if "help" in f.metadata]


def flag_of(cls: type, name: str) -> str:
    """The command-line flag of field ``name`` of ``cls``."""
    field = {f.name: f for f in dataclasses.fields(cls)}[name]
    if field.default is True:
        return "--no-" + name.replace("_", "-")
    return "--" + name.replace("_", "-")


class _ExplicitNone:
    """What a flag holds when its text parsed to None ("off"): given, unlike a flag left at None."""

    def __repr__(self) -> str:
        return "EXPLICIT_NONE"


EXPLICIT_NONE = _ExplicitNone()


def _parser(parse: Callable[[str], Any]) -> Callable[[str], Any]:
    """``parse`` with ValueError turned into argparse's error (so the message reaches the user); a text that
    parses to None (e.g. ``--lr-check off``) gives EXPLICIT_NONE, so that it is not taken for "not given"."""
    def convert(text: str) -> Any:
        try:
            value = parse(text)
        except ValueError as exc:
            raise argparse.ArgumentTypeError(str(exc)) from None
        return EXPLICIT_NONE if value is None else value

    convert.__name__ = getattr(parse, "__name__", "value")
    return convert


def _scalar_type(field: dataclasses.Field) -> type:
    """int, float or str: from the default value, else from the annotation (``int | None``)."""
    default = field.default
    if isinstance(default, (tuple, list)) and default:
        default = default[0]
    for kind in (int, float, str):
        if type(default) is kind:
            return kind
    annotation = str(field.type)
    for kind in (int, float, str):
        if kind.__name__ in annotation.replace("|", " ").split():
            return kind
    raise TypeError(f"field {field.name!r}: cannot derive a command-line type; give metadata 'parse'")


def _shown(value: Any, field: dataclasses.Field) -> str:
    """A default as its flag is written: values given as several words (``--depth-range 0.3 80.0``) with spaces,
    a pair read from one word (the census window (9, 7)) as ``9x7``, as the config and the docs write it."""
    if isinstance(value, (tuple, list)):
        return (" " if "nargs" in field.metadata else "x").join(str(v) for v in value)
    return str(value)


def add_options(group: Any, cls: type, *, defaults: Any = None, dest_prefix: str = "",
                show_defaults: Any = None, help_overrides: Mapping[str, str] | None = None) -> None:
    """Add one flag per option field of dataclass ``cls`` to an argparse parser or group.

    Parameters
    ----------
    group : argparse parser or argument group
    cls : dataclass type
    defaults : instance of ``cls`` or None
        Its values become the flags' defaults; None leaves every unset flag None (so that only the flags
        given can be merged over a config file).
    dest_prefix : str
        Put before each field name to form the argparse ``dest``.
    show_defaults : instance of ``cls`` or None
        Values to name in the help as "(default ...)" when ``defaults`` is None.
    help_overrides : mapping, optional
        Field name -> help text replacing the field's own.
    """
    overrides = dict(help_overrides or {})
    shown = defaults if defaults is not None else show_defaults
    for field in option_fields(cls):
        meta = field.metadata
        text = overrides.get(field.name, meta["help"])
        kwargs: dict[str, Any] = {}
        if isinstance(field.default, bool):
            kwargs.update(action="store_const", const=not field.default)
        else:
            kwargs["type"] = _parser(meta["parse"]) if "parse" in meta else _scalar_type(field)
            for key in ("metavar", "choices", "nargs"):
                if key in meta:
                    kwargs[key] = meta[key]
            value = getattr(shown, field.name) if shown is not None else None
            if value is not None and field.name not in overrides:
                text += f" (default: {_shown(value, field)})"
        default = getattr(defaults, field.name) if defaults is not None else None
        group.add_argument(flag_of(cls, field.name), dest=f"{dest_prefix}{field.name}", default=default,
                           help=text.replace("%", "%%"), **kwargs)


def read_options(args: argparse.Namespace, cls: type, *, dest_prefix: str = "",
                 given_only: bool = False) -> dict[str, Any]:
    """{field: value} of every option field of ``cls`` (None where unset and no default was given, or where
    the flag said "off"). ``given_only``: only the flags given on the command line (an "off" among them as
    None), for merging over a config file and the dataclass's defaults."""
    out = {}
    for f in option_fields(cls):
        value = getattr(args, f"{dest_prefix}{f.name}")
        if given_only and value is None:
            continue
        out[f.name] = None if value is EXPLICIT_NONE else value
    return out


def option_names(message: str, *classes: type) -> str:
    """Name the command-line flag in a message that names a field of ``classes`` in backticks.

    >>> from stereo_classic.matching import SGMParams
    >>> option_names("`p2` must be larger than `p1`", SGMParams)
    '--p2 must be larger than --p1'
    """
    for cls in classes:
        for field in option_fields(cls):
            message = message.replace(f"`{field.name}`", flag_of(cls, field.name))
    return message
