"""File input and output: images, PFM, KITTI and Middlebury disparity maps, PLY point clouds.

Every reader checks its file before it allocates anything and raises ``FileNotFoundError`` (missing
file, or a directory where a file was expected) or :class:`FileFormatError` (a ``ValueError``: empty,
truncated, lying or unsupported file) with the path in the message. Every writer is atomic: it writes
a temporary file in the target folder and renames it over the target with :func:`os.replace`, so a
failed write never leaves a half-written file behind.

Inside the project disparity is float32 pixels with NaN for unknown; the scale factors of the file
formats (KITTI x256, Middlebury x4/x8/x16, PFM ``inf``) exist only in this module.

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

import contextlib
import os
import re
import secrets
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any, NamedTuple

import cv2
import numpy as np

__all__ = [
    "FileFormatError",
    "PointCloud",
    "atomic_write",
    "read_image",
    "write_image",
    "read_pfm",
    "write_pfm",
    "read_kitti_disparity",
    "write_kitti_disparity",
    "read_scaled_disparity",
    "write_scaled_disparity",
    "read_ply",
    "write_ply",
]

PathLike = str | os.PathLike


class FileFormatError(ValueError):
    """A file exists but its content is not what the reader expects (empty, truncated, wrong format)."""


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


# --------------------------------------------------------------------------------------------------
# paths and atomic writes
# --------------------------------------------------------------------------------------------------


def _as_path(path: Any, name: str = "path") -> Path:
    if isinstance(path, (str, os.PathLike)):
        text = os.fspath(path)
        if isinstance(text, bytes):
            text = os.fsdecode(text)
        if text == "":
            raise ValueError(f"`{name}` must be a non-empty file path, got ''")
        return Path(text)
    raise TypeError(f"`{name}` must be a str or os.PathLike file path, got {type(path).__name__}")


def _existing_file(path: Any, what: str) -> Path:
    """Return ``path`` as a Path after checking that it is a non-empty regular file."""
    p = _as_path(path)
    if not p.exists():
        raise FileNotFoundError(f"{what} file not found: {p}")
    if p.is_dir():
        raise FileNotFoundError(f"{what}: expected a file, got a directory: {p}")
    size = p.stat().st_size
    if size == 0:
        raise FileFormatError(f"{what} file is empty (0 bytes): {p}")
    return p


@contextlib.contextmanager
def atomic_write(path: PathLike, mode: str = "wb") -> Iterator[IO[Any]]:
    """Open ``path`` for writing so that it appears complete or not at all.

    The body writes into a temporary file in the same folder; on success the file is flushed,
    synced and renamed over ``path`` (:func:`os.replace`, atomic on POSIX and Windows). If the body
    raises, the temporary file is removed and ``path`` is left as it was.

    Parameters
    ----------
    path : str or os.PathLike
        Target file. Its folder must exist.
    mode : {"wb", "w", "wt"}
        Binary (default) or text (UTF-8, ``\\n`` line ends).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> target = pathlib.Path(tempfile.mkdtemp()) / "a.txt"
    >>> with atomic_write(target, "w") as f:
    ...     _ = f.write("hello")
    >>> target.read_text()
    'hello'
    """
    if mode not in ("wb", "w", "wt"):
        raise ValueError(f"`mode` must be 'wb', 'w' or 'wt', got {mode!r}")
    target = _as_path(path)
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise FileNotFoundError(f"cannot write {target}: folder {parent} does not exist")
    if target.is_dir():
        raise IsADirectoryError(f"cannot write {target}: it is a directory")
    tmp = parent / f".{target.name}.{secrets.token_hex(6)}.tmp"
    # os.open with 0o666 lets the process umask decide the final permissions, like open() would.
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
    try:
        if mode == "wb":
            handle: IO[Any] = os.fdopen(fd, "wb")
        else:
            handle = os.fdopen(fd, "w", encoding="utf-8", newline="\n")
    except BaseException:
        os.close(fd)
        tmp.unlink(missing_ok=True)
        raise
    try:
        with handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


# --------------------------------------------------------------------------------------------------
# images
# --------------------------------------------------------------------------------------------------


def read_image(path: PathLike, *, grayscale: bool = False) -> np.ndarray:
    """Read an image file (PNG, JPEG, PGM/PPM, BMP, TIFF, ...).

    Unlike ``cv2.imread`` it never returns None, and it reads paths with any characters (it decodes
    the bytes with ``cv2.imdecode``).

    Parameters
    ----------
    path : str or os.PathLike
    grayscale : bool, keyword-only
        False (default): (H, W, 3) BGR, grey files are expanded to three equal channels, alpha is
        dropped. True: (H, W), colour files are converted to grey.

    Returns
    -------
    image : (H, W, 3) or (H, W) uint8, or uint16 when the file stores 16 bits.

    Raises
    ------
    FileNotFoundError
        The file does not exist or is a directory.
    FileFormatError
        Empty, truncated or not an image OpenCV can decode.
    """
    p = _existing_file(path, "image")
    data = np.fromfile(p, dtype=np.uint8)
    flags = cv2.IMREAD_ANYDEPTH | (cv2.IMREAD_GRAYSCALE if grayscale else cv2.IMREAD_COLOR)
    try:
        image = cv2.imdecode(data, flags)
    except cv2.error:
        image = None
    if image is None or image.size == 0:
        raise FileFormatError(
            f"cannot decode image {p} ({data.size} bytes): not an image format OpenCV reads, or the "
            "file is truncated or corrupt"
        )
    if image.dtype not in (np.uint8, np.uint16):
        raise FileFormatError(
            f"image {p} has pixel type {image.dtype}; expected 8- or 16-bit (use read_pfm for float maps)"
        )
    return image


def _check_image_array(image: Any, name: str = "image") -> np.ndarray:
    if not isinstance(image, np.ndarray):
        raise TypeError(f"`{name}` must be a numpy array, got {type(image).__name__}")
    if image.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"`{name}` must have dtype uint8 or uint16, got {image.dtype}")
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[:, :, 0]
    if not (image.ndim == 2 or (image.ndim == 3 and image.shape[2] in (3, 4))):
        raise ValueError(f"`{name}` must have shape (H, W), (H, W, 3) or (H, W, 4), got {image.shape}")
    if image.shape[0] == 0 or image.shape[1] == 0:
        raise ValueError(f"`{name}` must not be empty, got shape {image.shape}")
    return image


def _encode(path: Path, image: np.ndarray, params: list[int] | tuple[int, ...] = ()) -> bytes:
    ext = path.suffix.lower()
    if not ext:
        raise ValueError(f"cannot tell the image format of {path}: the file name has no extension")
    try:
        ok, buf = cv2.imencode(ext, image, list(params))
    except cv2.error as exc:
        raise ValueError(f"OpenCV cannot write {image.dtype} {image.shape} images as {ext!r} ({path}): {exc}") from exc
    if not ok:
        raise ValueError(f"OpenCV cannot write {image.dtype} {image.shape} images as {ext!r} ({path})")
    return buf.tobytes()


def write_image(path: PathLike, image: np.ndarray, *, params: list[int] | tuple[int, ...] = ()) -> None:
    """Write an image atomically; the format comes from the file extension (``.png``, ``.jpg``, ...).

    Parameters
    ----------
    path : str or os.PathLike
    image : (H, W), (H, W, 3) BGR or (H, W, 4) BGRA, uint8 or uint16
    params : OpenCV ``imwrite`` flags, e.g. ``(cv2.IMWRITE_JPEG_QUALITY, 95)``.
    """
    p = _as_path(path)
    image = _check_image_array(image)
    data = _encode(p, np.ascontiguousarray(image), params)
    with atomic_write(p, "wb") as f:
        f.write(data)


# --------------------------------------------------------------------------------------------------
# PFM
# --------------------------------------------------------------------------------------------------

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
    p = _existing_file(path, "PFM")
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


def _as_real_array(values: Any, name: str) -> np.ndarray:
    if not isinstance(values, np.ndarray):
        raise TypeError(f"`{name}` must be a numpy array, got {type(values).__name__}")
    if values.dtype == bool or not (np.issubdtype(values.dtype, np.integer) or np.issubdtype(values.dtype, np.floating)):
        raise ValueError(f"`{name}` must be a real integer or floating array, got dtype {values.dtype}")
    return values


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
    p = _as_path(path)
    a = _as_real_array(array, "array")
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


# --------------------------------------------------------------------------------------------------
# disparity PNG / PGM (KITTI, Middlebury)
# --------------------------------------------------------------------------------------------------


def _read_single_channel(path: PathLike, what: str) -> tuple[Path, np.ndarray]:
    p = _existing_file(path, what)
    data = np.fromfile(p, dtype=np.uint8)
    try:
        image = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    except cv2.error:
        image = None
    if image is None or image.size == 0:
        raise FileFormatError(f"cannot decode {what} {p}: not a PNG/PGM OpenCV reads, or truncated/corrupt")
    if image.ndim == 3:
        # some tools save grey maps as RGB with three equal channels: accept those only
        if image.shape[2] >= 3 and np.array_equal(image[:, :, 0], image[:, :, 1]) and np.array_equal(
            image[:, :, 0], image[:, :, 2]
        ):
            image = np.ascontiguousarray(image[:, :, 0])
        else:
            raise FileFormatError(f"{what} {p} must be a single-channel image, got {image.shape[2]} channels")
    return p, image


def read_kitti_disparity(path: PathLike) -> np.ndarray:
    """Read a KITTI 2012/2015 disparity PNG (uint16, disparity x 256, 0 = unknown).

    Returns
    -------
    disparity : (H, W) float32, pixels, NaN where unknown.
    """
    p, raw = _read_single_channel(path, "KITTI disparity")
    if raw.dtype != np.uint16:
        raise FileFormatError(f"KITTI disparity {p} must be a 16-bit PNG, got {raw.dtype}")
    disparity = raw.astype(np.float32) / np.float32(256.0)
    disparity[raw == 0] = np.nan
    return disparity


def _check_disparity(disparity: Any, name: str = "disparity") -> np.ndarray:
    d = _as_real_array(disparity, name)
    if d.ndim != 2 or d.shape[0] == 0 or d.shape[1] == 0:
        raise ValueError(f"`{name}` must be a non-empty (H, W) array, got shape {d.shape}")
    return d.astype(np.float64, copy=False)


def write_kitti_disparity(path: PathLike, disparity: np.ndarray) -> None:
    """Write a disparity map as a KITTI 16-bit PNG (x 256, rounded; NaN -> 0 = unknown), atomically.

    A known disparity of exactly 0 is stored as 1/256 px (the KITTI devkit does the same) so it stays
    known. Negative values, +-inf and values above 65535/256 (~256 px) cannot be stored and raise
    ``ValueError``.
    """
    p = _as_path(path)
    d = _check_disparity(disparity)
    known = ~np.isnan(d)
    vals = d[known]
    if vals.size:
        bad = ~np.isfinite(vals) | (vals < 0) | (vals > 65535 / 256.0)
        if bad.any():
            raise ValueError(
                "`disparity` values must be NaN (unknown) or in [0, 255.996] px for a KITTI PNG, got "
                f"{int(bad.sum())} values outside (min {np.min(vals)}, max {np.max(vals)})"
            )
    raw = np.zeros(d.shape, dtype=np.uint16)
    raw[known] = np.clip(np.rint(vals * 256.0), 1, 65535).astype(np.uint16)
    if p.suffix.lower() != ".png":
        raise ValueError(f"KITTI disparity must be written as .png, got {p.name}")
    data = _encode(p, raw)
    with atomic_write(p, "wb") as f:
        f.write(data)


def _check_scale(scale: Any) -> float:
    if isinstance(scale, bool) or not isinstance(scale, (int, float, np.integer, np.floating)):
        raise TypeError(f"`scale` must be a number, got {type(scale).__name__}")
    s = float(scale)
    if not np.isfinite(s) or s <= 0:
        raise ValueError(f"`scale` must be a positive finite number, got {scale}")
    return s


def read_scaled_disparity(path: PathLike, scale: float) -> np.ndarray:
    """Read a Middlebury-style integer disparity map (PGM or PNG, 8 or 16 bit): value = disparity x scale.

    Parameters
    ----------
    path : str or os.PathLike
    scale : float
        Stored value per pixel of disparity: 16 for Tsukuba ``disp3.pgm``, 8 for Venus
        ``disp2.pgm``, 4 for the quarter-size Cones/Teddy ``disp2.png``, 1 for 2005/2006 maps and
        for the Adirondack ground truth in ``../shared/data``.

    Returns
    -------
    disparity : (H, W) float32, pixels, NaN where the stored value is 0 (unknown).
    """
    s = _check_scale(scale)
    p, raw = _read_single_channel(path, "disparity map")
    if raw.dtype not in (np.uint8, np.uint16):
        raise FileFormatError(f"disparity map {p} must be 8- or 16-bit, got {raw.dtype}")
    disparity = (raw.astype(np.float64) / s).astype(np.float32)
    disparity[raw == 0] = np.nan
    return disparity


def write_scaled_disparity(path: PathLike, disparity: np.ndarray, scale: float, *, bits: int = 8) -> None:
    """Write a disparity map as a Middlebury-style integer PGM/PNG (value = round(d x scale), 0 = unknown).

    Values that round to 0 are stored as 1 so that they stay known. Negative values, inf and values
    above the range of ``bits`` raise ``ValueError``.
    """
    p = _as_path(path)
    s = _check_scale(scale)
    if bits not in (8, 16):
        raise ValueError(f"`bits` must be 8 or 16, got {bits}")
    d = _check_disparity(disparity)
    top = 255 if bits == 8 else 65535
    known = ~np.isnan(d)
    vals = d[known] * s
    if vals.size:
        bad = ~np.isfinite(vals) | (vals < 0) | (np.rint(vals) > top)
        if bad.any():
            raise ValueError(
                f"`disparity` x scale must be NaN or in [0, {top}] for a {bits}-bit map, got {int(bad.sum())} "
                f"values outside (max disparity {np.max(d[known])}, scale {s})"
            )
    raw = np.zeros(d.shape, dtype=np.uint8 if bits == 8 else np.uint16)
    raw[known] = np.clip(np.rint(vals), 1, top)
    data = _encode(p, raw)
    with atomic_write(p, "wb") as f:
        f.write(data)


# --------------------------------------------------------------------------------------------------
# PLY
# --------------------------------------------------------------------------------------------------

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
    p = _as_path(path)
    _check_color_order(color_order)
    pts = _as_real_array(points, "points")
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
    p = _existing_file(path, "PLY")
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
