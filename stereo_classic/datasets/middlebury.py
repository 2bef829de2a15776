"""Middlebury loaders: 2014 / MiddEval3 scene folders, the 2001-2006 sets, and ``<Name>_left/_right`` pairs.

Scale factors of the ground-truth files (PFM ``inf``, x16, x8, x4, full-resolution disparities in
reduced-size maps) are resolved here through :mod:`stereo_classic.io`; scenes hold float32 pixels with
NaN for unknown.

Usage (needs files that are not part of the package)::

    from stereo_classic.datasets import load_middlebury2014
    scene = load_middlebury2014("../shared/data/middlebury2014/trainingQ/Motorcycle")
    scene.max_disparity, round(scene.rig.baseline_m, 6)
    # -> (70, 0.193001)
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from calib import RectifiedRig, read_middlebury_calib
from stereo_classic.datasets.scene import (
    Scene,
    _check_shape,
    _find,
    _folder,
    _named_pairs,
    _need,
    _range_from_gt,
    _read_mask,
    _read_pair,
)
from stereo_classic.io import FileFormatError, read_pfm, read_scaled_disparity

__all__ = ["load_middlebury2014", "load_middlebury_classic", "load_named_pair"]


def load_middlebury2014(folder: str | os.PathLike) -> Scene:
    """Load one Middlebury 2014 / MiddEval3 scene folder (e.g. ``trainingQ/Motorcycle``).

    Reads ``im0``/``im1``, ``disp0GT.pfm`` (or ``disp0.pfm``; ``inf`` -> NaN), ``mask0nocc.png``
    (255 = non-occluded; pixels with unknown ground truth are False), and ``calib.txt`` (rig via
    :meth:`calib.RectifiedRig.from_middlebury`, baseline converted from mm; ``max_disparity`` =
    ``ndisp``). Files other than the images are optional (test scenes have no ground truth).
    """
    d = _folder(folder, "Middlebury 2014 scene folder")
    left, right = _read_pair(_need(d, "im0", "left image"), _need(d, "im1", "right image"))
    hw = left.shape[:2]
    gt = None
    gt_path = _find(d, "disp0GT", (".pfm",)) or _find(d, "disp0", (".pfm",))
    if gt_path is not None:
        raw = read_pfm(gt_path)
        if raw.ndim != 2:
            raise FileFormatError(f"ground truth {gt_path} must be a grey PFM, got {raw.shape[2]} channels")
        _check_shape(raw, hw, gt_path, "ground truth")
        gt = np.where(np.isfinite(raw), raw, np.nan).astype(np.float32)
    mask = None
    mask_path = _find(d, "mask0nocc", (".png",))
    if mask_path is not None:
        mask = _read_mask(mask_path, hw)
        if gt is not None:
            mask &= np.isfinite(gt)
    rig, max_disp = None, None
    calib_path = d / "calib.txt"
    if calib_path.is_file():
        rig = RectifiedRig.from_middlebury(calib_path, image_size=(hw[1], hw[0]))
        ndisp = read_middlebury_calib(calib_path).get("ndisp")
        if ndisp is not None:
            if isinstance(ndisp, np.ndarray) or not (math.isfinite(ndisp) and float(ndisp).is_integer()):
                raise FileFormatError(f"{calib_path}: ndisp must be a whole number, got {ndisp!r}")
            max_disp = int(ndisp)
    if max_disp is None or max_disp <= 0:
        max_disp = _range_from_gt(gt)
    return Scene(d.name, left, right, gt, mask, rig, None, max_disp, None, "middlebury2014", d)


#: (left stem, right stem, ground-truth stem, {gt extension: scale or None}) of the older Middlebury sets;
#: None: the map stores full-resolution disparities, the scale follows from the image width.
_CLASSIC_LAYOUTS: tuple[tuple[str, str, str, dict[str, float | None]], ...] = (
    ("im3", "im4", "disp3", {".pgm": 16.0, ".png": 16.0}),  # 2001 Tsukuba
    ("im2", "im6", "disp2", {".pgm": 8.0, ".png": None}),  # 2001 Venus & co (pgm x8), 2003 Cones/Teddy (png)
    ("view1", "view5", "disp1", {".png": None, ".pgm": None}),  # 2005 / 2006
)

#: Full-resolution width and the published sizes (factors) of the sets whose maps hold
#: full-resolution disparities: 2003 Cones/Teddy 1800 px (full, half, quarter), 2005/2006
#: 1240..1396 px (full, half, third).
_FULL_SIZES = {"im2": (1800, (1, 2, 4)), "view1": (1390, (1, 2, 3))}


def _full_resolution_scale(left_stem: str, width: int) -> float:
    """Stored value per pixel of disparity for maps that hold full-resolution disparities.

    The published size whose width is nearest: 2003 full 1800 px (x1), half 900 (x2), quarter 450
    (x4); 2005/2006 full 1240..1396 (x1), half 620..698 (x2), third 413..465 (x3).
    """
    full, factors = _FULL_SIZES[left_stem]
    return float(min(factors, key=lambda f: abs(full / f - width)))


def _classic_layout(d: Path) -> tuple[str, str, str, dict[str, float | None]] | None:
    for layout in _CLASSIC_LAYOUTS:
        if _find(d, layout[0]) is not None and _find(d, layout[1]) is not None:
            return layout
    return None


def load_middlebury_classic(folder: str | os.PathLike, *, disparity_scale: float | None = None) -> Scene:
    """Load a Middlebury 2001, 2003, 2005 or 2006 scene folder.

    Ground-truth scale (stored value = disparity x scale, 0 = unknown), as the datasets define it:

    * 2001 Tsukuba ``im3``/``im4`` + ``disp3.pgm``: x16;
    * 2001 Venus, Sawtooth, Bull, Poster, Barn ``im2``/``im6`` + ``disp2.pgm``: x8;
    * 2003 Cones/Teddy ``im2``/``im6`` + ``disp2.png``: the maps hold full-resolution disparities,
      so quarter size (450 px wide, the common download) is x4, half size x2, full size x1;
    * 2005/2006 ``view1``/``view5`` + ``disp1.png``: likewise full-resolution disparities, so third
      size (about 450 px wide) is x3, half size x2, full size (about 1390 px) x1.

    For 2003 and 2005/2006 the published size nearest to the image width gives the factor. Pass
    ``disparity_scale`` to override. These datasets have no calibration: ``rig`` is None and
    ``max_disparity`` is the largest ground truth rounded up to a multiple of 16.
    """
    d = _folder(folder, "Middlebury scene folder")
    layout = _classic_layout(d)
    if layout is None:
        raise FileNotFoundError(
            f"no Middlebury 2001-2006 pair in {d}: expected im3+im4 (Tsukuba), im2+im6 or view1+view5"
        )
    left_stem, right_stem, gt_stem, scales = layout
    left, right = _read_pair(_need(d, left_stem, "left image"), _need(d, right_stem, "right image"))
    gt = None
    gt_path = _find(d, gt_stem, tuple(scales))
    if gt_path is not None:
        scale = disparity_scale
        if scale is None:
            scale = scales[gt_path.suffix.lower()] or _full_resolution_scale(left_stem, left.shape[1])
        gt = read_scaled_disparity(gt_path, scale)
        _check_shape(gt, left.shape[:2], gt_path, "ground truth")
    year = {"im3": "2001", "view1": "2005/2006"}.get(left_stem)
    if year is None:
        year = "2001" if gt_path is not None and gt_path.suffix.lower() == ".pgm" else "2003"
    return Scene(d.name, left, right, gt, None, None, None, _range_from_gt(gt), None, f"middlebury{year}", d)



def load_named_pair(
    folder: str | os.PathLike, name: str | None = None, *, disparity_scale: float = 1.0
) -> Scene:
    """Load a ``<Name>_left/_right`` pair with optional ``<Name>_gt.png`` and ``<Name>_mask.png``.

    This is the layout of ``../shared/data/adirondackQ`` (Middlebury 2014 Adirondack, quarter size,
    not the official file names): ``_gt.png`` 8-bit, disparity x ``disparity_scale`` (1), 0 = unknown;
    ``_mask.png`` 255 = non-occluded. No calibration: ``rig`` is None.

    Parameters
    ----------
    folder : folder holding the files
    name : pair name; may be omitted when the folder holds exactly one pair.
    """
    d = _folder(folder, "scene folder")
    if name is None:
        names = _named_pairs(d)
        if len(names) != 1:
            raise ValueError(
                f"`name` is needed: {d} holds {len(names)} <name>_left/<name>_right pairs ({', '.join(names[:5])})"
            )
        name = names[0]
    left, right = _read_pair(_need(d, f"{name}_left", "left image"), _need(d, f"{name}_right", "right image"))
    hw = left.shape[:2]
    gt = None
    gt_path = _find(d, f"{name}_gt", (".png", ".pgm", ".pfm"))
    if gt_path is not None:
        if gt_path.suffix.lower() == ".pfm":
            raw = read_pfm(gt_path)
            gt = np.where(np.isfinite(raw), raw, np.nan).astype(np.float32)
        else:
            gt = read_scaled_disparity(gt_path, disparity_scale)
        _check_shape(gt, hw, gt_path, "ground truth")
    mask = None
    mask_path = _find(d, f"{name}_mask", (".png",))
    if mask_path is not None:
        mask = _read_mask(mask_path, hw)
        if gt is not None:
            mask &= np.isfinite(gt)
    return Scene(name, left, right, gt, mask, None, None, _range_from_gt(gt), None, "named_pair", d)
