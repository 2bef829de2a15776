"""Finding scenes on disk: :func:`iter_scenes` walks a folder, :func:`load_scene` loads one, whatever the layout.

A folder is recognised by the files it holds (see :mod:`stereo_classic.datasets` for the table of
layouts); the matching per-layout loader does the reading.

Usage (needs files that are not part of the package)::

    from stereo_classic.datasets import iter_scenes
    [s.layout for s in iter_scenes("../shared/data/middlebury2003")]
    # -> ['middlebury2003', 'middlebury2003']
"""

from __future__ import annotations

import os
import re
import warnings
from collections.abc import Callable, Iterator
from functools import partial
from pathlib import Path

from stereo_classic.datasets.drivingstereo import (
    _drivingstereo_frames,
    _drivingstereo_splits,
    load_drivingstereo,
)
from stereo_classic.datasets.kitti import (
    _kitti_object_frames,
    _kitti_stereo_dirs,
    _kitti_stereo_frames,
    load_kitti_lidar_folder,
    load_kitti_object,
    load_kitti_stereo,
)
from stereo_classic.datasets.middlebury import (
    _classic_layout,
    load_middlebury2014,
    load_middlebury_classic,
    load_named_pair,
)
from stereo_classic.datasets.oakd import _OAKD_JSON, load_oakd
from stereo_classic.datasets.scene import (
    _IMAGE_EXTS,
    Scene,
    SceneRef,
    _find,
    _folder,
    _named_pairs,
)
from stereo_classic.io import FileFormatError

__all__ = ["iter_scene_refs", "iter_scenes", "load_scene"]


def _scan(d: Path) -> list[SceneRef] | None:
    """The scenes a folder holds as one layout, or None when it is not a scene folder.

    Each loader is a ``functools.partial`` of a module-level function: picklable, so a frame description can travel
    to another process (``run --executor dask``) and be read there.
    """
    if _find(d, "im0") is not None and _find(d, "im1") is not None:
        return [(d.name, partial(load_middlebury2014, d))]
    if _classic_layout(d) is not None:
        return [(d.name, partial(load_middlebury_classic, d))]
    if (d / "calib.txt").is_file() and (_find(d, "lidar", (".bin",)) or _find(d, "velodyne", (".bin",))):
        return [(d.name, partial(load_kitti_lidar_folder, d))]
    if (d / "image_2").is_dir() and (d / "image_3").is_dir() and (d / "calib").is_dir() and (d / "velodyne").is_dir():
        return [(fid, partial(load_kitti_object, d, fid)) for fid in _kitti_object_frames(d)]
    splits = _drivingstereo_splits(d)
    if splits:
        return [
            (fid, partial(load_drivingstereo, d, fid, split=s))
            for s in splits
            for fid in _drivingstereo_frames(d, s)
        ]
    dirs = _kitti_stereo_dirs(d)
    if dirs is not None:
        return [(fid, partial(load_kitti_stereo, d, fid)) for fid in _kitti_stereo_frames(d, dirs)]
    names = _named_pairs(d)
    if names:
        if (d / _OAKD_JSON).is_file():
            return [(n, partial(load_oakd, d, n)) for n in names]
        return [(n, partial(load_named_pair, d, n)) for n in names]
    return None


def _unpaired_lefts(d: Path) -> list[str]:
    """``<name>_left`` images of ``d`` without a ``<name>_right`` image (a scan skips them)."""
    out = []
    for left in sorted(d.glob("*_left.*")):
        if left.suffix.lower() in _IMAGE_EXTS:
            name = left.name[: -len("_left" + left.suffix)]
            if _find(d, f"{name}_right") is None:
                out.append(left.name)
    return out


def iter_scene_refs(root: str | os.PathLike, *,
                    on_skip: Callable[[str], None] | None = None) -> Iterator[tuple[str, Path, Callable[[], Scene]]]:
    """Every scene at or below ``root`` as ``(name, folder, load)``, in sorted path order, none of them read.

    ``load()`` reads the scene (a picklable ``functools.partial``). ``on_skip`` is called with one line for
    each thing found but not a scene: a ``<name>_left`` image without its ``<name>_right``.
    """
    top = _folder(root, "dataset folder")
    stack = [top]
    while stack:
        d = stack.pop()
        refs = _scan(d)
        if on_skip is not None:
            for left in _unpaired_lefts(d):
                on_skip(f"{d / left}: a left image without a right image ({left.replace('_left', '_right', 1)})")
        if refs is not None:
            for name, load in refs:
                yield name, d, load
            continue
        subdirs = sorted((p for p in d.iterdir() if p.is_dir() and not p.name.startswith(".")), reverse=True)
        stack.extend(subdirs)


def iter_scenes(root: str | os.PathLike, *, skip_errors: bool = False) -> Iterator[Scene]:
    """Every scene found at or below ``root``, in sorted path order, loaded one at a time.

    A folder recognised as a layout (see the module docstring) is not searched further; hidden folders
    are skipped.

    Parameters
    ----------
    root : folder to search
    skip_errors : bool, keyword-only
        False (default): a scene that fails to load raises (``FileNotFoundError``/``ValueError`` naming
        the file). True: it is skipped with a ``UserWarning`` that says which and why.
    """
    for name, d, load in iter_scene_refs(root):
        try:
            scene = load()
        except (OSError, ValueError) as exc:
            if not skip_errors:
                raise
            warnings.warn(f"skipped scene {name!r} in {d}: {exc}", UserWarning, stacklevel=2)
            continue
        yield scene


def _first_scene_folder_below(d: Path, depth: int = 3) -> Path | None:
    if depth == 0:
        return None
    try:
        subdirs = sorted(p for p in d.iterdir() if p.is_dir() and not p.name.startswith("."))
    except OSError:
        return None
    for sub in subdirs:
        if _scan(sub):
            return sub
        found = _first_scene_folder_below(sub, depth - 1)
        if found is not None:
            return found
    return None


def load_scene(path: str | os.PathLike) -> Scene:
    """Load the scene at ``path``, whatever its layout.

    ``path`` may be a scene folder (Middlebury, Adirondack-style, KITTI LiDAR frame folder), a pair
    name inside a folder of ``<name>_left/_right`` pairs (``.../oakd/toy``), or the left image of such
    a pair (``.../oakd/toy_left.png``). Folders holding several scenes (KITTI, OAK-D, DrivingStereo) raise
    ``ValueError`` pointing at :func:`iter_scenes` or the per-layout loader.
    """
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"`path` must be a str or os.PathLike, got {type(path).__name__}")
    p = Path(os.fspath(path))
    if p.is_file():
        m = re.fullmatch(r"(.+)_left", p.stem)
        if m and p.suffix.lower() in _IMAGE_EXTS:
            p = p.parent / m.group(1)
        else:
            raise ValueError(f"`path` {p} is a file: pass a scene folder or a <name>_left image")
    if not p.exists():
        if p.parent.is_dir() and _find(p.parent, f"{p.name}_left") is not None:
            if (p.parent / _OAKD_JSON).is_file():
                return load_oakd(p.parent, p.name)
            return load_named_pair(p.parent, p.name)
        raise FileNotFoundError(f"scene not found: {p}")
    refs = _scan(p)
    if refs is None:
        below = _first_scene_folder_below(p)
        if below is not None:
            raise ValueError(
                f"{p} is not a scene folder but holds scenes below it (e.g. {below}): use "
                f"iter_scenes({str(p)!r}) or load_scene on one of them"
            )
        raise FileFormatError(
            f"no supported stereo layout in {p}: expected Middlebury (im0/im1, im2/im6, im3/im4, view1/view5), "
            "<name>_left/_right, KITTI (image_2/image_3), a KITTI frame with calib.txt + lidar.bin or DrivingStereo "
            "(train-left-image/train-right-image)"
        )
    if len(refs) != 1:
        names = ", ".join(name for name, _ in refs[:4])
        raise ValueError(
            f"{p} holds {len(refs)} scenes ({names}, ...): use iter_scenes({str(p)!r}) or the loader of its "
            "layout with a name or frame (load_oakd, load_named_pair, load_kitti_stereo, load_kitti_object, "
            "load_drivingstereo)"
        )
    return refs[0][1]()
