"""PLY point clouds: binary little-endian writer, reader for binary (either endian) and ASCII vertices.

Example
-------
>>> import numpy as np, tempfile, pathlib
>>> from stereo_classic.io import read_ply, write_ply
>>> path = pathlib.Path(tempfile.mkdtemp()) / "cloud.ply"
>>> write_ply(path, np.array([[0.0, 0.0, 1.0], [np.nan, 0.0, 2.0]]))
1
>>> points, colors = read_ply(path)
>>> points.tolist(), colors
([[0.0, 0.0, 1.0]], None)
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from stereo_classic.io._common import PathLike, as_path, as_real_array, existing_file
from stereo_classic.io.atomic import atomic_write
from stereo_classic.io.errors import FileFormatError

__all__ = ["PointCloud", "read_ply", "write_ply"]


class PointCloud(NamedTuple):
    """What :func:`read_ply` returns; unpacks as ``points, colors = read_ply(path)``.

    Attributes
    ----------
    points : (N, 3) float32
        x, y, z as stored (metres when written by this project).
    colors : (N, 3) uint8 or None
        Per-point colour in the order asked for (BGR by default), None when the file has none.
    """

    points: np.ndarray
    colors: np.ndarray | None


_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip


def _check_color_order(color_order: str) -> None:
    if color_order not in ("bgr", "rgb"):
        raise ValueError(f"`color_order` must be 'bgr' or 'rgb', got {color_order!r}")


def write_ply(
    path: PathLike,
    points: np.ndarray,
    colors: np.ndarray | None = None,
    *,
    color_order: str = "bgr",
    drop_invalid: bool = True,
) -> int:
    """Write a point cloud as binary little-endian PLY (float x, y, z; uchar red, green, blue), atomically.

    Parameters
    ----------
    path : str or os.PathLike
    points : (N, 3) or (H, W, 3) real array
        Coordinates, metres in this project (e.g. ``rig.points(disparity)``).
    colors : (N, 3) or (H, W, 3) uint8, optional
        One colour per point, in ``color_order`` (BGR by default, like images read with OpenCV).
    color_order : {"bgr", "rgb"}, keyword-only
    drop_invalid : bool, keyword-only
        True (default): points with any NaN/inf coordinate are left out (with their colours).
        False: non-finite points raise ``ValueError``.

    Returns
    -------
    count : int, number of vertices written.
    """
    p = as_path(path)
    _check_color_order(color_order)
    pts = as_real_array(points, "points")
    if pts.ndim < 2 or pts.shape[-1] != 3:
        raise ValueError(f"`points` must have shape (N, 3) or (H, W, 3), got {pts.shape}")
    pts = pts.reshape(-1, 3)
    cols = None
    if colors is not None:
        if not isinstance(colors, np.ndarray):
            raise TypeError(f"`colors` must be a numpy array or None, got {type(colors).__name__}")
        if colors.dtype != np.uint8:
            raise ValueError(f"`colors` must have dtype uint8, got {colors.dtype}")
        if colors.ndim < 2 or colors.shape[-1] != 3 or colors.size // 3 != pts.shape[0]:
            raise ValueError(
                f"`colors` must have shape (N, 3) matching `points` (N = {pts.shape[0]}), got {colors.shape}"
            )
        cols = colors.reshape(-1, 3)
    pts64 = pts.astype(np.float64, copy=False)
    finite = np.isfinite(pts64).all(axis=1)
    if not finite.all():
        if not drop_invalid:
            raise ValueError(f"`points` has {int((~finite).sum())} rows with NaN/inf (pass drop_invalid=True)")
        pts64 = pts64[finite]
        cols = cols[finite] if cols is not None else None
    if pts64.size and np.abs(pts64).max() > np.finfo(np.float32).max:
        raise ValueError("`points` has coordinates beyond the float32 range")
    n = pts64.shape[0]
    fields = [("x", "<f4"), ("y", "<f4"), ("z", "<f4")]
    if cols is not None:
        fields += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    rec = np.empty(n, dtype=np.dtype(fields))
    rec["x"], rec["y"], rec["z"] = pts64[:, 0], pts64[:, 1], pts64[:, 2]
    if cols is not None:
        rgb = cols[:, ::-1] if color_order == "bgr" else cols
        rec["red"], rec["green"], rec["blue"] = rgb[:, 0], rgb[:, 1], rgb[:, 2]
    header = ["ply", "format binary_little_endian 1.0", "comment written by stereo_classic", f"element vertex {n}"]
    header += ["property float x", "property float y", "property float z"]
    if cols is not None:
        header += ["property uchar red", "property uchar green", "property uchar blue"]
    header.append("end_header")
    with atomic_write(p, "wb") as f:
        f.write(("\n".join(header) + "\n").encode("ascii"))
        f.write(rec.tobytes())
    return n


def read_ply(path: PathLike, *, color_order: str = "bgr") -> PointCloud:
    """Read the vertices of a PLY file (binary little/big-endian or ASCII).

    Only the first element must be ``vertex`` with scalar properties including x, y, z; elements after
    it (faces, ...) are ignored. ``red``/``green``/``blue`` (uchar) become the colours.

    Returns
    -------
    PointCloud(points (N, 3) float32, colors (N, 3) uint8 in ``color_order`` or None)

    Raises
    ------
    FileNotFoundError, FileFormatError
        Missing file; bad header, unsupported layout, or fewer data bytes than the header promises
        (checked before reading the data).
    """
    _check_color_order(color_order)
    p = existing_file(path, "PLY")
    size = p.stat().st_size
    with open(p, "rb") as f:
        if f.read(4) not in (b"ply\n", b"ply\r"):
            raise FileFormatError(f"{p} is not a PLY file: it must start with 'ply'")
        f.seek(0)
        lines: list[str] = []
        while True:
            raw = f.readline(1024)
            if not raw:
                raise FileFormatError(f"PLY {p}: header has no 'end_header' line")
            if len(lines) > 1000 or not raw.endswith(b"\n"):
                raise FileFormatError(f"PLY {p}: header is malformed (overlong line or too many lines)")
            try:
                line = raw.decode("ascii").strip()
            except UnicodeDecodeError:
                raise FileFormatError(f"PLY {p}: header is not ASCII text") from None
            lines.append(line)
            if line == "end_header":
                break
        data_start = f.tell()
        fmt = None
        elements: list[tuple[str, int, list[tuple[str, str]]]] = []
        for line in lines[1:-1]:
            words = line.split()
            if not words or words[0] in ("comment", "obj_info"):
                continue
            if words[0] == "format" and len(words) == 3:
                fmt = words[1]
            elif words[0] == "element" and len(words) == 3:
                try:
                    count = int(words[2])
                except ValueError:
                    raise FileFormatError(f"PLY {p}: bad element count in {line!r}") from None
                if count < 0:
                    raise FileFormatError(f"PLY {p}: negative element count in {line!r}")
                elements.append((words[1], count, []))
            elif words[0] == "property" and elements:
                if len(words) == 3 and words[1] in _PLY_TYPES:
                    elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
                elif words[1] == "list":
                    if elements[-1][0] == "vertex":
                        raise FileFormatError(f"PLY {p}: list properties in 'vertex' are not supported")
                    elements[-1][2].append((words[-1], "list"))
                else:
                    raise FileFormatError(f"PLY {p}: unsupported property line {line!r}")
            else:
                raise FileFormatError(f"PLY {p}: unexpected header line {line!r}")
        if fmt not in ("binary_little_endian", "binary_big_endian", "ascii"):
            raise FileFormatError(f"PLY {p}: format must be binary_little_endian, binary_big_endian or ascii, got {fmt!r}")
        if not elements or elements[0][0] != "vertex":
            raise FileFormatError(f"PLY {p}: the first element must be 'vertex'")
        _, n, props = elements[0]
        names = [name for name, _ in props]
        if len(set(names)) != len(names) or not {"x", "y", "z"} <= set(names):
            raise FileFormatError(f"PLY {p}: vertex needs distinct properties including x, y, z, got {names}")
        if fmt == "ascii":
            text = f.read().decode("ascii", errors="replace").split()
            need = n * len(props)
            if len(text) < need:
                raise FileFormatError(f"PLY {p} is truncated: header says {n} vertices, data holds {len(text)} of {need} values")
            try:
                table = np.array(text[:need], dtype=np.float64).reshape(n, len(props))
            except ValueError:
                raise FileFormatError(f"PLY {p}: vertex data is not numeric") from None
            columns = {name: table[:, i] for i, name in enumerate(names)}
        else:
            endian = "<" if fmt == "binary_little_endian" else ">"
            dtype = np.dtype([(name, endian + t) for name, t in props])
            need = n * dtype.itemsize
            if size - data_start < need:
                raise FileFormatError(
                    f"PLY {p} is truncated: header says {n} vertices x {dtype.itemsize} bytes = {need} bytes, "
                    f"the file holds {size - data_start}"
                )
            rec = np.fromfile(f, dtype=dtype, count=n)
            columns = {name: rec[name] for name in names}
    points = np.stack([columns["x"], columns["y"], columns["z"]], axis=1).astype(np.float32)
    colors = None
    if {"red", "green", "blue"} <= set(names):
        rgb = np.stack([columns["red"], columns["green"], columns["blue"]], axis=1)
        if rgb.size and (np.nanmin(rgb) < 0 or np.nanmax(rgb) > 255):
            raise FileFormatError(f"PLY {p}: colours must be in 0..255")
        colors = rgb.astype(np.uint8)
        if color_order == "bgr":
            colors = np.ascontiguousarray(colors[:, ::-1])
    return PointCloud(points, colors)
