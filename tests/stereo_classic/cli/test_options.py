"""stereo_classic.cli.options: flags generated from the parameter dataclasses."""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from stereo_classic.cli.options import add_options, flag_of, option_fields, option_names, read_options
from stereo_classic.fusion import FusionParams
from stereo_classic.matching import SGMParams


@pytest.mark.parametrize("cls", [SGMParams, FusionParams])
def test_every_option_field_round_trips_through_its_flag(cls):
    parser = argparse.ArgumentParser()
    add_options(parser, cls, defaults=cls())
    defaults = read_options(parser.parse_args([]), cls)
    assert defaults == {f.name: getattr(cls(), f.name) for f in option_fields(cls)}
    flags = {s for a in parser._actions for s in a.option_strings}
    assert {flag_of(cls, f.name) for f in option_fields(cls)} <= flags


def test_no_defaults_leaves_unset_flags_none_and_shows_the_default_in_help():
    parser = argparse.ArgumentParser()
    add_options(parser, FusionParams, show_defaults=FusionParams())
    assert set(read_options(parser.parse_args([]), FusionParams).values()) == {None}
    text = parser.format_help()
    assert "--depth-range NEAR FAR" in text and "(default: 0.3 80.0)" in text


def test_switches_and_parsers():
    parser = argparse.ArgumentParser()
    add_options(parser, SGMParams)
    args = parser.parse_args(["--no-subpixel", "--adaptive-p2", "--census-window", "7x5", "--lr-check", "off",
                              "--paths", "4"])
    got = read_options(args, SGMParams)
    assert (got["subpixel"], got["adaptive_p2"], got["census_window"], got["lr_check"], got["paths"]) == (
        False, True, (7, 5), None, 4)
    params = SGMParams(**{k: v for k, v in got.items() if v is not None})
    assert params.census_window == (7, 5) and not params.subpixel


@pytest.mark.parametrize("argv", [["--census-window", "7"], ["--lr-check", "x"], ["--paths", "5"],
                                  ["--num-disparities", "1.5"]])
def test_bad_values_are_usage_errors(argv, capsys):
    parser = argparse.ArgumentParser()
    add_options(parser, SGMParams)
    with pytest.raises(SystemExit) as exc:
        parser.parse_args(argv)
    assert exc.value.code == 2
    assert argv[0] in capsys.readouterr().err


def test_flags_are_the_field_names_and_fields_without_help_are_not_flags():
    assert flag_of(SGMParams, "subpixel") == "--no-subpixel"
    assert flag_of(SGMParams, "fill_holes") == "--no-fill-holes"
    names = {f.name for f in option_fields(SGMParams)}
    assert {"threads", "memory_limit", "right_view"}.isdisjoint(names)
    assert {"max_samples", "max_iterations", "max_clusters"}.isdisjoint({f.name for f in option_fields(FusionParams)})
    assert all(isinstance(f.metadata["help"], str) and f.metadata["help"] for f in option_fields(SGMParams))
    assert len(dataclasses.fields(SGMParams)) - len(names) == 3


def test_option_names_puts_the_flag_into_messages():
    assert option_names("`box_shrink` must be in [0, 1)", FusionParams) == "--box-shrink must be in [0, 1)"
    assert option_names("`subpixel` and `p1`", SGMParams) == "--no-subpixel and --p1"


def test_help_shows_values_as_the_flags_take_them(capsys):
    """Issue 34: the census window as 9x7 (as the flag, the config and the docs write it), a range as two words,
    and --save's choices with ply (which it accepts)."""
    from stereo_classic.cli import main

    assert main(["disparity", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: 9x7)" in text
    assert main(["run", "--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    assert "metres (default: 0.3 80.0)" in text and "ply" in text.split("--save LIST")[-1].split("--ply")[0]
