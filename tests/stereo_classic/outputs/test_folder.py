"""stereo_classic.outputs.folder: one run per folder, settings recorded, resume must match, fresh runs clean up."""

from __future__ import annotations

import json

import pytest

from stereo_classic.cli import main
from stereo_classic.outputs import FolderBusyError, OutputFolder
from stereo_classic.outputs.folder import LOCK_NAME, RUN_NAME, settings_diff

PFM = ["{name}_disparity.pfm"]


def test_a_second_run_into_a_held_folder_fails_naming_the_holder(tmp_path):
    with OutputFolder(tmp_path, {"seed": 0}, outputs=PFM):
        (tmp_path / "a_disparity.pfm").write_bytes(b"x")
        with pytest.raises(FolderBusyError, match=r"in use by another run \(process \d+\)"):
            OutputFolder(tmp_path, {"seed": 0}, outputs=PFM).__enter__()
    with OutputFolder(tmp_path, {"seed": 0}, outputs=PFM, resume=True):  # released: usable again
        pass


def test_the_command_refuses_a_folder_another_run_holds(tmp_path, capsys):
    out = tmp_path / "o"
    with OutputFolder(out, {}, outputs=PFM):
        assert main(["run", "--model", "none", "--scale", "0.25", "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert f"output folder {out} is in use by another run" in err and err.count("\n") == 1


def test_resume_with_other_settings_is_refused_saying_what_differs(tmp_path, capsys):
    out = tmp_path / "o"
    base = ["-q", "run", "--model", "none", "--scale", "0.25", "--save", "pfm,json", "-o", str(out)]
    assert main(base) == 0
    settings = json.loads((out / RUN_NAME).read_text())["settings"]
    assert settings["scale"] == 0.25 and settings["input"] == {"demo": True} and "threads" not in settings
    assert main([*base, "--resume", "--seed", "3", "--p1", "12"]) == 2
    err = capsys.readouterr().err
    assert "seed: the folder's run had 0, this run has 3" in err and "matcher.p1: the folder's run had " in err
    assert main([*base, "--resume", "--threads", "1"]) == 0  # how, not what: resumes


def test_a_fresh_run_removes_what_the_earlier_run_wrote_and_nothing_else(tmp_path):
    out = tmp_path / "o"
    assert main(["-q", "run", "--model", "none", "--scale", "0.25", "-o", str(out)]) == 0
    assert (out / "motorcycle_skimage_boxes.png").is_file()
    (out / "notes.txt").write_text("mine")
    (out / ".motorcycle_skimage_depth.png.0123456789ab.tmp").write_bytes(b"half")
    assert main(["-q", "run", "--model", "none", "--scale", "0.25", "--save", "pfm", "-o", str(out)]) == 0
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [LOCK_NAME, RUN_NAME, "motorcycle_skimage_disparity.pfm", "notes.txt"])


def test_a_run_that_writes_nothing_leaves_nothing(tmp_path):
    with OutputFolder(tmp_path / "new", {"seed": 0}, outputs=PFM):
        pass
    assert not (tmp_path / "new").exists()


def test_settings_diff_lists_every_difference():
    assert settings_diff({"a": 1, "m": {"x": [1, 2]}}, {"a": 1, "m": {"x": [1, 3]}, "b": True}) == [
        "b: the folder's run had '(not set)', this run has true", "m.x: the folder's run had [1, 2], this run has [1, 3]"]
