"""``run --executor dask`` without Dask installed: one line saying what to install, exit 2, nothing written."""

from __future__ import annotations

import importlib

from stereo_classic.cli import main


def test_without_dask_the_command_says_what_to_install(tmp_path, monkeypatch, capsys):
    real = importlib.import_module

    def no_distributed(name, *args):
        if name == "distributed" or name.startswith("distributed."):
            raise ImportError("No module named 'distributed'")
        return real(name, *args)

    monkeypatch.setattr(importlib, "import_module", no_distributed)
    assert main(["run", "--model", "none", "--executor", "dask", "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and 'pip install "stereo-classic[dask]"' in err
    assert not (tmp_path / "o").exists()
