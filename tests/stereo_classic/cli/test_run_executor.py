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


def test_the_run_options_of_scale_out_are_config_keys(tmp_path, capsys):
    config = tmp_path / "c.toml"
    config.write_text('on_error = "skip"\nexecutor = "serial"\n')
    assert main(["run", "--config", str(config), "--dump-config"]) == 0
    dumped = capsys.readouterr().out
    assert 'on_error = "skip"' in dumped and 'executor = "serial"' in dumped and 'scheduler = ""' in dumped
    config.write_text('executor = "spark"\n')
    assert main(["run", "--config", str(config), "--model", "none", "-o", str(tmp_path / "o")]) == 2
    assert "`executor` (--executor) must be one of serial, dask, got 'spark'" in capsys.readouterr().err
    assert main(["run", "--scheduler", "tcp://127.0.0.1:1", "-o", str(tmp_path / "o")]) == 2
    assert "--scheduler goes with --executor dask" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()
