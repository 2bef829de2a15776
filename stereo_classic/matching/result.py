"""The matcher's result: ``DisparityMap`` (measured by default, filled by name; a per-pixel confidence)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import InitVar, dataclass, field

import numpy as np
from numba import njit

from stereo_classic.matching.params import SGMParams

__all__ = ["DisparityMap"]


@njit(cache=True, nogil=True)
def _split_filled(disp, filled, measured):  # pragma: no cover - numba
    """One pass over a C-contiguous map and its filled mask: ``measured`` = ``disp`` with NaN where ``filled``;
    returns (finite pixels, infinite pixels, filled pixels whose value is NaN, filled pixels). The checks and the
    copy of ``DisparityMap.__post_init__``, which took five NumPy passes and a masked assignment (0.55 ms at VGA,
    on the matcher's one thread)."""
    d = disp.ravel()
    f = filled.ravel()
    m = measured.ravel()
    nan = np.float32(np.nan)
    zero = np.float32(0.0)
    n_finite = 0
    n_inf = 0
    n_bad = 0
    n_filled = 0
    for i in range(d.shape[0]):
        v = d[i]
        finite = v - v == zero
        n_finite += finite
        n_inf += (not finite) and v == v
        if f[i]:
            n_filled += 1
            n_bad += v != v
            m[i] = nan
        else:
            m[i] = v
    return n_finite, n_inf, n_bad, n_filled


# --------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class DisparityMap:
    """A disparity map with the parameters that made it, per-stage timings and a validity summary. Measured by
    default, filled by name: ``disparity`` holds what was measured, ``filled_disparity`` the map with holes filled.

    Attributes
    ----------
    disparity : (H, W) float32
        Left-view disparity in pixels, ``d = x_left - x_right``, measured pixels only: NaN where unknown or filled.
        The constructor takes the matcher's map with its fills (``filled``) and moves them to ``filled_disparity``.
    disparity_right : (H, W) float32 or None
        Right-view disparity (pixels, integer winner-takes-all over the same sums, NaN where no
        candidate) when ``params.right_view`` is set or the "full" left-right check computed it.
    params : SGMParams
        The parameters used.
    timings_ms : dict[str, float]
        Milliseconds per stage: "prepare" (checks + grey conversion), "features" (learned costs: the network), the
        matcher's stages ("cost", "aggregate", "select", as reported by the kernels; "aggregate" includes the speckle
        filter's labelling when it is made stripe by stripe beside the matching), "postprocess", "total".
    validity : dict[str, int | None]
        Pixel counts: "pixels" (H * W), "valid" (known in ``filled_disparity``: measured + filled), "unknown_matcher"
        (NaN out of the matcher) = "no_candidate" (columns where no disparity of the range lands inside
        the right image) + "failed_lr" + "failed_uniqueness" + "outside" (won by a match outside the right image at
        its neutral cost, ``SGMParams.outside_match``) (exact counts from the kernels), "short_range"
        (border pixels set unknown because they could search less than ``border_reach`` of the range),
        "speckle_removed", "filled" (by ``fill_holes``), "border" (pixels in the image bands where the full disparity
        range does not fit, matched with the range that does) and "border_valid".
    filled : (H, W) bool or None
        True where ``filled_disparity`` holds a value filled in by ``fill_holes`` (NaN in ``disparity``); None
        when nothing was filled.
    left_gray : (H, W) uint8 or None
        The left image as matched (grey, a copy), kept for ``confidence``.

    ``confidence``: (H, W) uint8 per-pixel confidence of the measured pixels. ``measured_disparity``: an alias of
    ``disparity`` (its name before it became the default).
    """

    disparity: np.ndarray
    disparity_right: np.ndarray | None
    params: SGMParams
    timings_ms: dict[str, float] = field(default_factory=dict)
    validity: dict[str, int | None] = field(default_factory=dict)
    filled: np.ndarray | None = None
    left_gray: np.ndarray | None = None
    _one_pass: InitVar[tuple | None] = None  # (measured map, counts): ``_of_one_pass``'s, instead of the pass below

    def __post_init__(self, _one_pass: tuple | None) -> None:
        disp = self.disparity
        if not isinstance(disp, np.ndarray) or disp.ndim != 2 or disp.dtype != np.float32:
            raise ValueError(f"`disparity` must be a (H, W) float32 array, got "
                             f"{type(disp).__name__} {getattr(disp, 'shape', None)} {getattr(disp, 'dtype', None)}")
        filled = self.filled
        fast = (isinstance(filled, np.ndarray) and filled.shape == disp.shape and filled.dtype == np.bool_
                and disp.flags.c_contiguous and filled.flags.c_contiguous)  # the matcher's maps: one pass
        if fast and _one_pass is not None:  # made by the post-processing beside ``disparity``
            measured, (n_valid, n_inf, n_bad, n_filled) = _one_pass
            if not (isinstance(measured, np.ndarray) and measured.shape == disp.shape and measured.dtype == disp.dtype):
                raise ValueError(f"`_one_pass` must hold a float32 map of shape {disp.shape}")
        elif fast:
            measured = np.empty_like(disp)
            n_valid, n_inf, n_bad, n_filled = _split_filled(disp, filled, measured)
        if (n_inf > 0) if fast else np.isinf(disp).any():
            raise ValueError("`disparity` must hold finite values or NaN (unknown), got inf")
        for name, dtype in (("disparity_right", np.float32), ("filled", np.bool_), ("left_gray", np.uint8)):
            arr = getattr(self, name)
            if arr is not None and (not isinstance(arr, np.ndarray) or arr.shape != disp.shape or arr.dtype != dtype):
                raise ValueError(f"`{name}` must be None or a {np.dtype(dtype).name} array of shape {disp.shape}, got "
                                 f"{getattr(arr, 'shape', type(arr).__name__)} {getattr(arr, 'dtype', '')}")
        if not isinstance(self.params, SGMParams):
            raise ValueError(f"`params` must be an SGMParams, got {type(self.params).__name__}")
        if not isinstance(self.timings_ms, Mapping) or not all(
                isinstance(k, str) and isinstance(v, (int, float)) and math.isfinite(v) and v >= 0
                for k, v in self.timings_ms.items()):
            raise ValueError(f"`timings_ms` must map stage names to non-negative milliseconds, got {self.timings_ms!r}")
        object.__setattr__(self, "timings_ms", {k: float(v) for k, v in self.timings_ms.items()})
        if not isinstance(self.validity, Mapping) or not all(
                isinstance(k, str) and (v is None or (isinstance(v, (int, np.integer)) and v >= 0))
                for k, v in self.validity.items()):
            raise ValueError(f"`validity` must map names to non-negative pixel counts or None, got {self.validity!r}")
        validity = {k: (None if v is None else int(v)) for k, v in self.validity.items()}
        if not fast:
            n_valid = int(np.count_nonzero(np.isfinite(disp)))
        if validity.get("valid", n_valid) != n_valid or validity.get("pixels", disp.size) != disp.size:
            raise ValueError(f"`validity` does not describe `disparity`: it says {validity.get('valid')} valid of "
                             f"{validity.get('pixels')}, the map has {n_valid} of {disp.size}")
        validity["valid"] = n_valid
        validity["pixels"] = int(disp.size)
        object.__setattr__(self, "validity", validity)
        if (n_bad > 0) if fast else (filled is not None and np.count_nonzero(filled & np.isnan(disp))):
            raise ValueError("`filled` marks pixels whose disparity is unknown (NaN)")
        # Measured by default: the fills move to ``filled_disparity``, ``disparity`` keeps the measured pixels.
        object.__setattr__(self, "_filled_disparity", disp)
        if (n_filled > 0) if fast else (filled is not None and filled.any()):
            if not fast:
                measured = disp.copy()
                measured[filled] = np.nan
            object.__setattr__(self, "disparity", measured)

    @classmethod
    def _of_one_pass(cls, filled_disparity: np.ndarray, filled: np.ndarray, measured: np.ndarray, kept: int,
                     n_filled: int, **fields) -> DisparityMap:
        """``DisparityMap(disparity=filled_disparity, filled=filled, **fields)`` for the matcher's post-processing in
        one pass (``postprocess._speckle_fill_counted``), which made ``measured`` (NaN where ``filled``) and counted
        the ``kept`` and ``n_filled`` pixels beside the filled map: the constructor takes them instead of its own pass
        over the maps. What that pass checks holds by how the one pass makes them (kept pixels are finite values of
        the speckle filter's regions, filled ones the minimum or median of such values, every filled pixel known);
        every other check is made as always."""
        counts = (int(kept) + int(n_filled), 0, 0, int(n_filled))
        return cls(disparity=filled_disparity, filled=filled, _one_pass=(measured, counts), **fields)

    @property
    def filled_disparity(self) -> np.ndarray:
        """(H, W) float32: ``disparity`` with the holes ``fill_holes`` filled (marked in ``filled``: guesses from the
        background, never a distance); ``disparity`` itself when nothing was filled."""
        return self.__dict__["_filled_disparity"]

    @property
    def confidence(self) -> np.ndarray:
        """(H, W) uint8: how far each measured disparity can be trusted, 1 .. 255; 0 where nothing was measured
        (unknown or filled). Computed on first read, not while matching (``matching.confidence.confidence_map``)."""
        cached = self.__dict__.get("_confidence")
        if cached is None:
            from stereo_classic.matching.confidence import confidence_map

            cached = confidence_map(self.disparity, self.disparity_right, self.left_gray,
                                    lr_check=self.params.lr_check)
            cached.flags.writeable = False
            object.__setattr__(self, "_confidence", cached)
        return cached

    @property
    def measured_disparity(self) -> np.ndarray:
        """Alias of ``disparity`` (the measured pixels), for code written when ``disparity`` was the filled map."""
        return self.disparity

    @property
    def measured_fraction(self) -> float:
        """Fraction (0..1) of pixels with a measured (not filled) disparity; the same as ``valid_fraction``."""
        return self.valid_fraction

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the map."""
        return self.disparity.shape  # type: ignore[return-value]

    @property
    def valid_mask(self) -> np.ndarray:
        """(H, W) bool, True where the disparity was measured (finite in ``disparity``)."""
        return np.isfinite(self.disparity)

    @property
    def valid_fraction(self) -> float:
        """Fraction (0..1) of pixels with a measured disparity (filled ones do not count)."""
        n_filled = 0 if self.filled is None else int(np.count_nonzero(self.filled))
        return (self.validity["valid"] - n_filled) / max(1, self.disparity.size)  # type: ignore[operator]
