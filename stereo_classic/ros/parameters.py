"""ROS parameters generated from the parameter dataclasses (``SGMParams``, ``FusionParams``, ``GuideParams``), as the
command line's flags are (:mod:`stereo_classic.cli.options`): the same fields (those with a help text), the same
defaults, the same parsers, nothing retyped.

A field becomes the parameter ``PREFIX.FIELD`` (``matcher.num_disparities``, ``fusion.box_shrink``,
``guide.corridor_width``): a bool, int, float or str field a parameter of that type with the field's default; a
tuple of numbers (``depth_range``) a number array; a field whose flag has its own parser or whose default is None
(``census_window``, ``lr_check``, ``camera_height``) a string, "" meaning the dataclass's default and any other text
read as its flag reads it ("9x7", "off").

>>> from stereo_classic.fusion import FusionParams
>>> table = {p.name: p for p in parameter_table(FusionParams, "fusion")}
>>> table["fusion.depth_range"].default, table["fusion.box_shrink"].default
([0.3, 80.0], 0.2)
>>> dataclass_values(FusionParams, "fusion", {"fusion.box_shrink": 0.1, "fusion.depth_range": [0.3, 80.0]})
{'box_shrink': 0.1}
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from typing import Any

from stereo_classic.cli.options import _scalar_type, option_fields

__all__ = ["Parameter", "dataclass_values", "parameter_table"]


@dataclasses.dataclass(frozen=True)
class Parameter:
    """One ROS parameter: its name, default (a ROS parameter value: bool, int, float, str or a list of numbers),
    description and the conversion of its value to the field's value (None: the dataclass's default)."""

    name: str
    field: str
    default: Any
    description: str
    convert: Callable[[Any], Any]


def _identity(value: Any) -> Any:
    return value


def parameter_table(cls: type, prefix: str, defaults: Mapping[str, Any] | None = None) -> list[Parameter]:
    """The ROS parameters of dataclass ``cls`` (its command-line option fields), named ``prefix.field``;
    ``defaults`` (field -> value) replaces fields' defaults (the commands' ``num_disparities`` of 128)."""
    instance = cls()
    out = []
    for f in option_fields(cls):
        value = (defaults or {}).get(f.name, getattr(instance, f.name))
        meta = f.metadata
        text = meta["help"]
        if isinstance(value, (bool, int, float, str)) and "parse" not in meta:
            default, convert = value, _identity
        elif isinstance(value, tuple) and value and all(isinstance(v, (int, float)) for v in value) \
                and "parse" not in meta:
            kind = float if any(isinstance(v, float) for v in value) else int
            default = [kind(v) for v in value]
            convert = (lambda k: lambda v: tuple(k(x) for x in v))(kind)
        else:
            parse = meta.get("parse") or _scalar_type(f)
            default = ""
            text += " ('' = default" + (f" {value}" if value is not None else "") + ")"
            convert = (lambda p: lambda v: None if v == "" else p(v))(parse)
        out.append(Parameter(f"{prefix}.{f.name}", f.name, default, text, convert))
    return out


def dataclass_values(cls: type, prefix: str, values: Mapping[str, Any],
                     defaults: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The fields whose parameter (in ``values``, name -> value) differs from the dataclass's default, converted
    (``defaults``: as for :func:`parameter_table`; a field given there is always returned).

    Raises
    ------
    ValueError
        A value its field's parser refuses (the message names the parameter).
    """
    out = {}
    for p in parameter_table(cls, prefix, defaults):
        if p.name not in values or (values[p.name] == p.default and p.field not in (defaults or {})):
            continue
        try:
            value = p.convert(values[p.name])
        except (TypeError, ValueError) as exc:
            raise ValueError(f"parameter {p.name}: {exc}") from None
        out[p.field] = value
    return out
