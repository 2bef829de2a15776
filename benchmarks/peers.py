"""Accuracy peers outside OpenCV: CNES Pandora with its C++ libSGM plugin (the extra ``.[peers]``).

``pandora``: census 5x5 + libSGM (8 paths, P1 8, P2 32, constant P2), winner-takes-all, V-fit subpixel, a 3x3 median
before and after Pandora's "accurate" cross check (1 px): the configuration of issue 35 (Pandora 1.9.0,
pandora-plugin-libsgm 1.5.8, Apache-2.0). It runs on the grey image (OpenCV's BGR-to-grey weights, as this matcher)
and is single-threaded whatever the setup says: an accuracy peer, not a speed peer.

Pandora's conventions, converted here: its left disparity is ``x_right - x_left``, so the search is
``[-(D-1), -min_disparity]`` and the result is negated; plugins register only after ``pandora.import_plugin()``; an
invalid pixel is one whose ``validity_mask`` has a bit of ``Criteria.PANDORA_MSK_PIXEL_INVALID`` (not a NaN).
Without the extra the method is listed as not available with one line saying how to install it.
"""

from __future__ import annotations

import importlib.util
import logging
from typing import Any

import cv2
import numpy as np

__all__ = ["PANDORA_DESCRIPTION", "PANDORA_PIPELINE", "pandora_available", "pandora_factory"]

#: What the ``pandora`` method is, for the report.
PANDORA_DESCRIPTION = ("CNES Pandora 1.9.0 + libSGM 1.5.8: census 5x5, 8 paths, P1 8 / P2 32, WTA, V-fit subpixel, 3x3 median "
                       "before and after the accurate cross check (1 px); grey input; single-threaded at every thread count")

#: The Pandora pipeline of the ``pandora`` method (``check_pipeline_section`` adds the defaults it leaves out).
PANDORA_PIPELINE: dict[str, dict[str, Any]] = {
    "matching_cost": {"matching_cost_method": "census", "window_size": 5, "subpix": 1},
    "optimization": {"optimization_method": "sgm", "overcounting": False,
                     "penalty": {"P1": 8, "P2": 32, "p2_method": "constant", "penalty_method": "sgm_penalty"}},
    "disparity": {"disparity_method": "wta", "invalid_disparity": "NaN"},
    "refinement": {"refinement_method": "vfit"},
    "filter": {"filter_method": "median", "filter_size": 3},
    "validation": {"validation_method": "cross_checking_accurate", "cross_checking_threshold": 1.0},
    "filter.after": {"filter_method": "median", "filter_size": 3},
}

_INSTALL = 'install the extra: pip install -e ".[peers]" (pandora 1.9.0, pandora-plugin-libsgm 1.5.8)'
_NODATA = -9999


def pandora_available() -> tuple[bool, str]:
    """``(True, "")`` when Pandora and its libSGM plugin can be imported, else ``(False, why)``."""
    missing = [m for m in ("pandora", "pandora_plugin_libsgm") if importlib.util.find_spec(m) is None]
    return (False, _INSTALL) if missing else (True, "")


def _dataset(grey: np.ndarray, disp: list[int]) -> Any:
    import xarray as xr
    from pandora import img_tools

    h, w = grey.shape
    ds = xr.Dataset({"im": (["row", "col"], grey)}, coords={"row": np.arange(h), "col": np.arange(w)},
                    attrs={"crs": None, "transform": None, "valid_pixels": 0, "no_data_mask": 1})
    ds = img_tools.add_disparity(ds, disp, None)
    nodata = np.where(grey == _NODATA)
    ds = img_tools.add_no_data(ds, _NODATA, nodata)
    return img_tools.add_mask(ds, None, nodata, w, h, None)


def _metadata(shape: tuple[int, int], disp: list[int]) -> Any:
    import xarray as xr
    from pandora import img_tools

    h, w = shape
    ds = xr.Dataset(data_vars={}, coords={"band_im": [None], "row": np.arange(h), "col": np.arange(w)})
    return img_tools.add_disparity(ds, disp, None)


def _grey(image: np.ndarray) -> np.ndarray:
    grey = image if image.ndim == 2 else cv2.cvtColor(np.ascontiguousarray(image), cv2.COLOR_BGR2GRAY)
    return np.ascontiguousarray(grey, dtype=np.float32)


def pandora_factory(setup: Any) -> Any:
    """A runner ``run(left, right) -> (H, W) float32 disparity, NaN unknown`` for a ``benchmarks.methods.Setup``
    (its range; its thread count is ignored: libSGM runs on one thread)."""
    import pandora
    from pandora import check_configuration
    from pandora.constants import Criteria
    from pandora.state_machine import PandoraMachine

    pandora.import_plugin()  # libSGM registers itself only here
    logging.getLogger("transitions").setLevel(logging.ERROR)  # a warning per binding of every new PandoraMachine
    invalid = int(Criteria.PANDORA_MSK_PIXEL_INVALID)
    lo, hi = setup.min_disparity, setup.min_disparity + setup.num_disparities - 1
    left_range, right_range = [-hi, -lo], [lo, hi]  # Pandora's left disparity is x_right - x_left

    def run(left: np.ndarray, right: np.ndarray) -> np.ndarray:
        if left.shape != right.shape:
            raise ValueError(f"`right` must have the left image's shape {left.shape}, got {right.shape}")
        machine = PandoraMachine()
        cfg = check_configuration.check_pipeline_section(
            {"pipeline": {k: dict(v) for k, v in PANDORA_PIPELINE.items()}},
            _metadata(left.shape[:2], left_range), _metadata(left.shape[:2], right_range), machine)
        out, _ = pandora.run(machine, _dataset(_grey(left), left_range), _dataset(_grey(right), right_range), cfg)
        disp = -np.asarray(out["disparity_map"].data, dtype=np.float32)
        disp[(np.asarray(out["validity_mask"].data).astype(np.int64) & invalid) != 0] = np.nan
        return disp

    return run
