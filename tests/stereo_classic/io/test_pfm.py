"""stereo_classic.io.pfm: round trips, row order and byte order, hostile headers, property tests."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from stereo_classic.io import FileFormatError, read_pfm, write_pfm

HYP = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@pytest.mark.parametrize("byteorder", ["little", "big"])
@pytest.mark.parametrize("shape", [(7, 5), (4, 6, 3)])
def test_pfm_round_trip(tmp_path: Path, byteorder: str, shape: tuple[int, ...]) -> None:
    rng = np.random.default_rng(3)
    a = rng.normal(size=shape).astype(np.float32)
    a.flat[0], a.flat[1], a.flat[2] = np.inf, -np.inf, np.nan
    write_pfm(tmp_path / "a.pfm", a, byteorder=byteorder)
    head = (tmp_path / "a.pfm").read_bytes()[:20]
    assert head.startswith(b"PF\n" if len(shape) == 3 else b"Pf\n")
    assert (b"\n-1.0\n" in head) == (byteorder == "little")
    b = read_pfm(tmp_path / "a.pfm")
    assert b.dtype == np.float32 and b.shape == shape and b.flags.c_contiguous
    np.testing.assert_array_equal(b, a)  # NaN == NaN for assert_array_equal


def test_pfm_rows_stored_bottom_up_and_scale_sign(tmp_path: Path) -> None:
    # hand-made file: 2 x 2, big-endian (positive scale), bottom row first
    body = struct.pack(">4f", 3.0, 4.0, 1.0, 2.0)
    (tmp_path / "h.pfm").write_bytes(b"Pf\n2 2\n2.5\n" + body)
    np.testing.assert_array_equal(read_pfm(tmp_path / "h.pfm"), [[1.0, 2.0], [3.0, 4.0]])
    body = struct.pack("<4f", 3.0, 4.0, 1.0, 2.0)
    (tmp_path / "l.pfm").write_bytes(b"Pf\n2 2\n-0.003922\n" + body)  # Middlebury writes -1/255
    np.testing.assert_array_equal(read_pfm(tmp_path / "l.pfm"), [[1.0, 2.0], [3.0, 4.0]])


@pytest.mark.parametrize(
    ("content", "match"),
    [
        (b"Pf\n100000 100000\n-1.0\n" + b"\0" * 16, "truncated"),  # lying header: 40 GB promised
        (b"Pf\n2 2\n-1.0\n" + b"\0" * 15, "truncated"),
        (b"Pf\n2 2\n-1.0\n" + b"\0" * 17, "longer"),
        (b"PF\n2 2\n-1.0\n" + b"\0" * 16, "truncated"),  # colour needs 48 bytes
        (b"P6\n2 2\n255\n" + b"\0" * 12, "not a PFM"),
        (b"Pf\n0 2\n-1.0\n", "positive"),
        (b"Pf\n2 2\n0\n" + b"\0" * 16, "non-zero"),
        (b"Pf\n2 2\nnan\n" + b"\0" * 16, "finite"),
        (b"Pf\n2 2\nabc\n" + b"\0" * 16, "PFM"),
        (b"Pf\n-2 2\n-1.0\n" + b"\0" * 16, "not a PFM"),
    ],
)
def test_pfm_hostile_files(tmp_path: Path, content: bytes, match: str) -> None:
    path = tmp_path / "bad.pfm"
    path.write_bytes(content)
    with pytest.raises(FileFormatError, match=match) as info:
        read_pfm(path)
    assert "bad.pfm" in str(info.value)


def test_pfm_missing_empty_directory(tmp_path: Path) -> None:
    with pytest.raises(FileNotFoundError, match="x.pfm"):
        read_pfm(tmp_path / "x.pfm")
    (tmp_path / "e.pfm").write_bytes(b"")
    with pytest.raises(FileFormatError, match="empty"):
        read_pfm(tmp_path / "e.pfm")
    with pytest.raises(FileNotFoundError, match="directory"):
        read_pfm(tmp_path)


def test_write_pfm_rejects_bad_input(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="shape"):
        write_pfm(tmp_path / "a.pfm", np.zeros((2, 2, 2), np.float32))
    with pytest.raises(ValueError, match="empty"):
        write_pfm(tmp_path / "a.pfm", np.zeros((0, 2), np.float32))
    with pytest.raises(ValueError, match="dtype"):
        write_pfm(tmp_path / "a.pfm", np.zeros((2, 2), complex))
    with pytest.raises(ValueError, match="float32 range"):
        write_pfm(tmp_path / "a.pfm", np.full((2, 2), 1e300))
    with pytest.raises(ValueError, match="byteorder"):
        write_pfm(tmp_path / "a.pfm", np.zeros((2, 2), np.float32), byteorder="middle")
    with pytest.raises(TypeError, match="array"):
        write_pfm(tmp_path / "a.pfm", [[1.0]])  # type: ignore[arg-type]
    assert not (tmp_path / "a.pfm").exists()


@HYP
@given(
    a=hnp.arrays(
        np.float32,
        st.tuples(st.integers(1, 9), st.integers(1, 9)).flatmap(
            lambda hw: st.sampled_from([hw, hw + (3,)])
        ),
        elements=st.floats(width=32, allow_nan=True, allow_infinity=True),
    ),
    byteorder=st.sampled_from(["little", "big"]),
)
def test_pfm_round_trip_property(tmp_path: Path, a: np.ndarray, byteorder: str) -> None:
    path = tmp_path / "p.pfm"
    write_pfm(path, a, byteorder=byteorder)
    np.testing.assert_array_equal(read_pfm(path), a)


@HYP
@given(tail=st.binary(max_size=64), w=st.integers(0, 10**9), h=st.integers(0, 10**9))
def test_pfm_random_bodies_never_crash(tmp_path: Path, tail: bytes, w: int, h: int) -> None:
    path = tmp_path / "r.pfm"
    path.write_bytes(f"Pf\n{w} {h}\n-1.0\n".encode() + tail)
    try:
        out = read_pfm(path)
    except FileFormatError as exc:
        assert "r.pfm" in str(exc)
    else:
        assert out.shape == (h, w) and 4 * w * h == len(tail)
