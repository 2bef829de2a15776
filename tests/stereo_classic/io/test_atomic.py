"""stereo_classic.io.atomic: a file appears complete or not at all."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from stereo_classic.io import atomic_write, write_kitti_disparity


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_atomic_write_success_and_failure(tmp_path: Path) -> None:
    target = tmp_path / "out.bin"
    with atomic_write(target) as f:
        f.write(b"first")
    assert target.read_bytes() == b"first"
    with pytest.raises(RuntimeError):
        with atomic_write(target) as f:
            f.write(b"half-writ")
            raise RuntimeError("boom")
    assert target.read_bytes() == b"first"  # old content untouched
    assert _leftovers(tmp_path) == []
    new = tmp_path / "never.txt"
    with pytest.raises(KeyError):
        with atomic_write(new, "w") as f:
            f.write("x")
            raise KeyError("boom")
    assert not new.exists() and _leftovers(tmp_path) == []


def test_atomic_write_text_mode_and_permissions(tmp_path: Path) -> None:
    target = tmp_path / "t.txt"
    with atomic_write(target, "w") as f:
        f.write("é\n")
    assert target.read_bytes() == "é\n".encode()
    umask = os.umask(0)
    os.umask(umask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask


def test_atomic_write_bad_arguments(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="mode"):
        with atomic_write(tmp_path / "a", "a"):
            pass
    with pytest.raises(IsADirectoryError):
        with atomic_write(tmp_path):
            pass
    with pytest.raises(FileNotFoundError, match="missing"):
        with atomic_write(tmp_path / "missing" / "a"):
            pass


def test_failed_writer_keeps_old_file(tmp_path: Path) -> None:
    path = tmp_path / "d.png"
    write_kitti_disparity(path, np.full((3, 3), 5.0, np.float32))
    before = path.read_bytes()
    with pytest.raises(ValueError):
        write_kitti_disparity(path, np.full((3, 3), -5.0, np.float32))
    assert path.read_bytes() == before and _leftovers(tmp_path) == []
