"""stereo_classic.cli.config: the TOML config of run, merged with flags."""

from __future__ import annotations

import re

import pytest


def test_merge_precedence_and_dump_round_trip(tmp_path):
    from stereo_classic.cli.config import RUN_DEFAULTS, dump_config, load_config, merge_config

    path = tmp_path / "c.toml"
    path.write_text('conf = 0.2\nseed = 3\nclasses = ["car"]\n[matcher]\nnum_disparities = 64\ncensus_window = [7, 5]\n')
    file_cfg = load_config(path)
    merged = merge_config(file_cfg, {"seed": 7, "conf": None}, {"cost": "sad"})
    assert merged["conf"] == 0.2 and merged["seed"] == 7 and merged["classes"] == ["car"]
    assert merged["matcher"] == {"num_disparities": 64, "census_window": (7, 5), "cost": "sad"}
    assert merged["box_shrink"] == RUN_DEFAULTS["box_shrink"][0]
    path.write_text(dump_config(merged))
    again = merge_config(load_config(path), {}, {})
    assert again == merged




def test_toml_accepts_every_value_form_the_flags_accept(tmp_path):
    from stereo_classic.cli.config import load_config

    path = tmp_path / "c.toml"
    path.write_text('scale = "0.5"\nmax_frames = "3"\nclasses = "car,person"\ndepth_range = "0.5 60"\n'
                    '[matcher]\ncensus_window = "7x5"\nlr_check = "off"\nnum_disparities = "64"\n')
    cfg = load_config(path)
    assert cfg["scale"] == 0.5 and cfg["max_frames"] == 3 and cfg["classes"] == ["car", "person"]
    assert cfg["depth_range"] == [0.5, 60.0]
    assert cfg["matcher"] == {"census_window": (7, 5), "lr_check": None, "num_disparities": 64}
    path.write_text('[matcher]\nlr_check = "1.5"\ncensus_window = [9, 7]\n')
    assert load_config(path)["matcher"] == {"lr_check": 1.5, "census_window": (9, 7)}


@pytest.mark.parametrize(("text", "match"), [
    ('[matcher]\ncensus_window = "9y"\n', r"\[matcher\] `census_window`: expected WIDTHxHEIGHT such as 9x7, got '9y'"),
    ('[matcher]\nlr_check = "sometimes"\n', r"`lr_check`: expected a number of pixels or 'off'"),
    ('scale = "half"\n', r"`scale` must be a finite number, got 'half'"),
    ('camera = "usb"\n', r"`camera` must be an integer"),
])
def test_toml_value_errors_name_the_key(tmp_path, text, match):
    from stereo_classic.cli.config import ConfigError, load_config

    path = tmp_path / "c.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=match):
        load_config(path)


def test_dump_config_holds_the_input_and_runs_it_back(tmp_path, capsys):
    from stereo_classic.cli import main

    calib = tmp_path / "rig.yaml"
    calib.write_text("x")
    argv = ["run", "--left", "a*.png", "--right", "b*.png", "--calib", str(calib), "--rectify", "--scale", "0.5",
            "--census-window", "7x5", "--dump-config"]
    assert main(argv) == 0
    dumped = capsys.readouterr().out
    for line in ('left = ["a*.png"]', 'right = ["b*.png"]', f'calib = "{calib}"', "rectify = true", "scale = 0.5",
                 "census_window = [7, 5]"):
        assert line in dumped.splitlines(), line
    cfg = tmp_path / "c.toml"
    cfg.write_text(dumped)
    assert main(["run", "--config", str(cfg), "--dump-config"]) == 0
    assert capsys.readouterr().out == dumped
    # an input kind given as a flag replaces the file's (no "choose one input" clash), other keys stay
    assert main(["run", "--config", str(cfg), "--dataset", str(tmp_path), "--dump-config"]) == 0
    again = capsys.readouterr().out.splitlines()
    assert f'dataset = "{tmp_path}"' in again and not any(line.startswith("left =") for line in again)
    assert "scale = 0.5" in again


def test_the_config_file_input_is_the_run_input(tmp_path, capsys):
    from stereo_classic.cli import main

    cfg = tmp_path / "c.toml"
    cfg.write_text(f'left = ["{tmp_path / "nope_L.png"}"]\nright = ["{tmp_path / "nope_R.png"}"]\n'
                   f'calib = "{tmp_path / "rig.yaml"}"\n')
    assert main(["run", "--config", str(cfg), "-o", str(tmp_path / "o")]) == 1
    assert "nope_L.png" in capsys.readouterr().err  # it tried the file's input, not the demo


@pytest.mark.parametrize(("text", "match"), [
    ("[matcher]\nnum_disparities = -5\n", r"`num_disparities` must be a positive integer"),
    ("[matcher]\ncensus_window = [9, 8]\n", r"`census_window` must be \(width, height\) of odd"),
])
def test_a_matcher_value_out_of_range_names_the_file(tmp_path, capsys, text, match):
    """Issue 34: SGMParams' own checks run on the file's table, so the error line names the file (exit 2)."""
    from stereo_classic.cli import main
    from stereo_classic.cli.config import ConfigError, load_config

    path = tmp_path / "c.toml"
    path.write_text(text)
    with pytest.raises(ConfigError, match=rf"^{re.escape(str(path))}: \[matcher\] {match}"):
        load_config(path)
    assert main(["run", "--config", str(path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"error: {path}: [matcher]")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("classes", [["car,person"], ["car", "person"], ["car,", "person"]])
def test_classes_with_commas_or_spaces_read_alike(capsys, classes):
    from stereo_classic.cli import main

    assert main(["run", "--classes", *classes, "--dump-config"]) == 0
    assert 'classes = ["car", "person"]' in capsys.readouterr().out
