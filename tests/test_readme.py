"""The README's quick start: its demo output is exactly what `python -m stereo_classic run` prints, offline."""

from __future__ import annotations

from tests.conftest import REPO


def _readme_demo_block() -> str:
    text = (REPO / "README.md").read_text(encoding="utf-8")
    quick = text[text.index("## Quick start"):text.index("## Install and configure")]
    blocks, current, kind = [], None, ""
    for line in quick.splitlines(keepends=True):
        if line.startswith("```"):
            if current is None:
                current, kind = [], line.strip()[3:]
            else:
                blocks.append((kind, "".join(current)))
                current = None
        elif current is not None:
            current.append(line)
    printed = [text for kind, text in blocks if kind == ""]  # the untyped block: the printed output
    assert len(printed) == 1, "the quick start holds one block of expected output"
    return printed[0]


def test_readme_demo_output_is_what_run_prints_with_no_model_variables(tmp_path, monkeypatch, capsys):
    from detectors import models
    from stereo_classic.cli import main

    monkeypatch.delenv("STEREO_CLASSIC_MODELS", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "empty_cache"))  # nothing fetched: the shipped model

    def no_download(*args, **kwargs):  # pragma: no cover - reaching it is the failure
        raise AssertionError("the quick start must not need the network")

    monkeypatch.setattr(models, "download_model", no_download)
    monkeypatch.chdir(tmp_path)
    assert main(["run"]) == 0
    captured = capsys.readouterr()
    assert captured.out == _readme_demo_block()
    assert "1 frame(s), 2 object(s), outputs in stereo_out" in captured.err
    assert (tmp_path / "stereo_out" / "motorcycle_skimage_objects.json").is_file()
