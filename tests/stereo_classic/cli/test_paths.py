"""stereo_classic.cli.paths and every command's output check: a bad output path fails before any work."""

from __future__ import annotations

import pytest

from stereo_classic.cli import UsageError, main
from stereo_classic.cli.paths import check_output_dir, check_output_file


def test_check_output_dir_and_file(tmp_path):
    (tmp_path / "file").write_text("x")
    assert check_output_dir(tmp_path / "a" / "b", "--out") == tmp_path / "a" / "b"
    assert check_output_file(tmp_path / "x.pfm", "-o") == tmp_path / "x.pfm"
    with pytest.raises(UsageError, match=r"--out .*file exists and is a file, not a folder"):
        check_output_dir(tmp_path / "file", "--out")
    with pytest.raises(UsageError, match=r"--out .*file/sub: .*file is a file, so the folder cannot be made"):
        check_output_dir(tmp_path / "file" / "sub", "--out")
    with pytest.raises(UsageError, match=r"-o .* is a folder, expected a file name"):
        check_output_file(tmp_path, "-o")
    with pytest.raises(UsageError, match=r"the folder .*missing' does not exist"):
        check_output_file(tmp_path / "missing" / "x.pfm", "-o")


def _no_work(*args, **kwargs):  # pragma: no cover - reaching it is the failure
    raise AssertionError("the command started working before checking its output path")


def test_run_checks_its_output_before_opening_the_input(tmp_path, capsys, monkeypatch):
    from stereo_classic.cli import run

    monkeypatch.setattr(run, "open_source", _no_work)
    (tmp_path / "taken").write_text("x")
    assert main(["run", "-o", str(tmp_path / "taken")]) == 2
    assert "exists and is a file, not a folder" in capsys.readouterr().err
    assert main(["run", "-o", str(tmp_path / "taken" / "out")]) == 2
    assert "is a file, so the folder cannot be made" in capsys.readouterr().err


def test_disparity_and_calibrate_check_their_output_first(tmp_path, capsys, monkeypatch):
    from stereo_classic import io

    monkeypatch.setattr(io, "read_image", _no_work)
    (tmp_path / "d.pfm").mkdir()
    assert main(["disparity", "l.png", "r.png", "-o", str(tmp_path / "d.pfm")]) == 2
    assert "is a folder, expected a file name" in capsys.readouterr().err
    (tmp_path / "rig.yaml").mkdir()
    argv = ["calibrate", "--folder", str(tmp_path / "none"), "--board-size", "9x6", "--square", "0.025",
            "-o", str(tmp_path / "rig.yaml")]
    assert main(argv) == 2
    assert "is a folder, expected a file name" in capsys.readouterr().err
