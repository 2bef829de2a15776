"""stereo_classic.io errors: every reader raises only FileNotFoundError or FileFormatError, naming the file."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stereo_classic.io import (
    FileFormatError,
    PointCloud,
    read_image,
    read_kitti_depth,
    read_kitti_disparity,
    read_pfm,
    read_ply,
    read_scaled_disparity,
)

HYP = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@HYP
@given(junk=st.binary(max_size=200))
def test_readers_on_random_bytes_raise_only_documented_errors(tmp_path: Path, junk: bytes) -> None:
    for name, reader in (
        ("j.png", read_image),
        ("j.pfm", read_pfm),
        ("j.ply", read_ply),
        ("k.png", read_kitti_disparity),
        ("z.png", read_kitti_depth),
        ("m.pgm", lambda p: read_scaled_disparity(p, 8)),
    ):
        path = tmp_path / name
        path.write_bytes(junk)
        try:
            out = reader(path)
        except FileFormatError as exc:
            assert name in str(exc)
        else:  # bytes that parse must give a well-formed result, not garbage
            _check_well_formed(name, out, len(junk))


def _check_well_formed(name: str, out: object, n_bytes: int) -> None:
    if name == "j.ply":
        assert isinstance(out, PointCloud)
        assert out.points.dtype == np.float32 and out.points.ndim == 2 and out.points.shape[1] == 3
        assert out.points.nbytes <= 4 * n_bytes  # at most one float per stored byte (ASCII "0 ")
        assert out.colors is None or (out.colors.dtype == np.uint8 and out.colors.shape == out.points.shape)
        return
    assert isinstance(out, np.ndarray) and out.size > 0, name
    if name == "j.png":
        assert out.dtype in (np.uint8, np.uint16) and (out.ndim == 2 or (out.ndim == 3 and out.shape[2] in (3, 4)))
    elif name == "j.pfm":
        assert out.dtype == np.float32 and (out.ndim == 2 or (out.ndim == 3 and out.shape[2] == 3))
        assert out.nbytes <= n_bytes  # the raster is stored uncompressed
    else:  # disparity and depth maps
        assert out.dtype == np.float32 and out.ndim == 2
        assert not np.isinf(out).any() and not (out < 0).any()


@pytest.mark.parametrize(
    "reader",
    [read_image, read_pfm, read_ply, read_kitti_disparity, read_kitti_depth, lambda p: read_scaled_disparity(p, 4)],
    ids=["image", "pfm", "ply", "kitti", "kitti_depth", "scaled"],
)
def test_every_reader_refuses_missing_empty_and_directories(tmp_path: Path, reader) -> None:  # noqa: ANN001
    with pytest.raises(FileNotFoundError, match="missing.bin"):
        reader(tmp_path / "missing.bin")
    folder = tmp_path / "folder.png"
    folder.mkdir()
    with pytest.raises(FileNotFoundError, match="directory"):
        reader(folder)
    (tmp_path / "empty.bin").write_bytes(b"")
    with pytest.raises(FileFormatError, match="empty"):
        reader(tmp_path / "empty.bin")
