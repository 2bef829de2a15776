"""PFM float maps (Middlebury ground truth): grey ``Pf`` or colour ``PF``, either byte order, rows bottom-up.

Values are returned as stored: ``inf`` (Middlebury's "unknown") stays ``inf`` here and becomes NaN in
the dataset loaders.

Example
-------
>>> import numpy as np, tempfile, pathlib
>>> from stereo_classic.io import write_pfm, read_pfm
>>> path = pathlib.Path(tempfile.mkdtemp()) / "d.pfm"
>>> write_pfm(path, np.arange(6, dtype=np.float32).reshape(2, 3))
>>> float(read_pfm(path)[1, 2])
5.0
"""

from __future__ import annotations

import re

import numpy as np

from stereo_classic.io._common import PathLike, as_path, as_real_array, existing_file
from stereo_classic.io.atomic import atomic_write
from stereo_classic.io.errors import FileFormatError

__all__ = ["read_pfm", "write_pfm"]

_PFM_HEADER = re.compile(rb"\A(P[Ff])\s+(\d{1,12})\s+(\d{1,12})\s+([-+0-9.eEinfINFaN]{1,40})(\r\n|\s)")


def read_pfm(path: PathLike) -> np.ndarray:
    """Read a PFM file (grey ``Pf`` or colour ``PF``, either byte order).

    PFM stores rows bottom-up; the array returned has the top row first. The byte order comes from the
    sign of the scale line (negative: little-endian). Values are returned as stored (the magnitude of
    the scale is ignored, as Middlebury does; ``inf`` stays ``inf``).

    Returns
    -------
    data : (H, W) or (H, W, 3) float32, C-contiguous, native byte order.

    Raises
    ------
    FileNotFoundError, FileFormatError
        Missing file; bad magic, bad header, or a header whose size disagrees with the file size
        (checked before any allocation).
    """
    p = existing_file(path, "PFM")
    size = p.stat().st_size
    with open(p, "rb") as f:
        head = f.read(128)
        m = _PFM_HEADER.match(head)
        if m is None:
            raise FileFormatError(
                f"{p} is not a PFM file: expected a header 'Pf' or 'PF', width, height and scale, got "
                f"{head[:32]!r}"
            )
        magic, w_txt, h_txt, s_txt, _ = m.groups()
        width, height = int(w_txt), int(h_txt)
        try:
            scale = float(s_txt)
        except ValueError:
            raise FileFormatError(f"PFM {p}: scale must be a number, got {s_txt!r}") from None
        if width <= 0 or height <= 0:
            raise FileFormatError(f"PFM {p}: width and height must be positive, got {width} x {height}")
        if not np.isfinite(scale) or scale == 0:
            raise FileFormatError(f"PFM {p}: scale must be a finite non-zero number, got {s_txt.decode()!r}")
        channels = 3 if magic == b"PF" else 1
        header_len = m.end()
        expected = width * height * channels * 4
        got = size - header_len
        if got != expected:
            kind = "truncated" if got < expected else "longer than its header says"
            raise FileFormatError(
                f"PFM {p} is {kind}: header says {width} x {height} x {channels} float32 = {expected} "
                f"bytes of data, the file holds {got}"
            )
        f.seek(header_len)
        dtype = np.dtype("<f4" if scale < 0 else ">f4")
        data = np.fromfile(f, dtype=dtype, count=width * height * channels)
    if data.size != width * height * channels:  # pragma: no cover - the size check above covers it
        raise FileFormatError(f"PFM {p} is truncated")
    shape = (height, width, 3) if channels == 3 else (height, width)
    return np.ascontiguousarray(data.reshape(shape)[::-1], dtype=np.float32)


def write_pfm(path: PathLike, array: np.ndarray, *, byteorder: str = "little") -> None:
    """Write a float array as PFM (atomically), rows bottom-up as the format requires.

    Parameters
    ----------
    path : str or os.PathLike
    array : (H, W), (H, W, 1) or (H, W, 3), real dtype
        Converted to float32; NaN and inf are written as they are. Finite values beyond the float32
        range raise ``ValueError`` instead of silently turning into inf.
    byteorder : {"little", "big"}, keyword-only
        Written as the sign of the scale (-1.0 little, 1.0 big).
    """
    p = as_path(path)
    a = as_real_array(array, "array")
    if a.ndim == 3 and a.shape[2] == 1:
        a = a[:, :, 0]
    if not (a.ndim == 2 or (a.ndim == 3 and a.shape[2] == 3)):
        raise ValueError(f"`array` must have shape (H, W), (H, W, 1) or (H, W, 3), got {a.shape}")
    if a.shape[0] == 0 or a.shape[1] == 0:
        raise ValueError(f"`array` must not be empty, got shape {a.shape}")
    if byteorder not in ("little", "big"):
        raise ValueError(f"`byteorder` must be 'little' or 'big', got {byteorder!r}")
    if np.issubdtype(a.dtype, np.floating) and a.dtype.itemsize > 4:
        finite = a[np.isfinite(a)]
        if finite.size and np.abs(finite).max() > np.finfo(np.float32).max:
            raise ValueError("`array` has finite values beyond the float32 range (|x| > 3.4e38)")
    dtype = np.dtype("<f4" if byteorder == "little" else ">f4")
    body = np.ascontiguousarray(a[::-1], dtype=dtype)
    magic = "PF" if body.ndim == 3 else "Pf"
    header = f"{magic}\n{body.shape[1]} {body.shape[0]}\n{-1.0 if byteorder == 'little' else 1.0}\n"
    with atomic_write(p, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(body.tobytes())
