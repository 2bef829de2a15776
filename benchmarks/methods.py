"""The stereo methods compared: this project's matcher, OpenCV StereoSGBM / StereoBM, ONNX networks.

Every method is run on the same input pair with the same disparity range (``min_disparity``,
``num_disparities``) and block size, except where a method's definition fixes them (the KITTI 2015
"OCV-SGBM" settings use block 3). Each returns a float32 (H, W) disparity in pixels with NaN where
unknown, so the metrics count every method's invalid border the same way.

A method whose output holds values it did not measure (this project's matcher fills its holes,
``SGMParams.fill_holes``, marked in ``DisparityMap.filled``) returns both: the output (scored in the
dense and unknown-is-bad views) and the measured pixels only (scored in the valid view), as a
``DisparityMap`` (``filled_disparity`` and ``disparity``) or a ``(output, measured)`` tuple; :func:`output_views`
reads either.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from benchmarks import peers

__all__ = [
    "OPENCV_COMMON",
    "Method",
    "Runner",
    "Setup",
    "default_methods",
    "opencv_methods",
    "opencv_to_disparity",
    "output_views",
    "peer_methods",
    "stereo_classic_methods",
    "timing_pair",
]

#: A prepared method: ``runner(left, right) -> (H, W) float32 disparity, NaN unknown`` (used for every view),
#: or an object with ``filled_disparity`` and ``disparity`` (a ``DisparityMap``) or an ``(output, measured)``
#: tuple when the output holds filled pixels (see :func:`output_views`).
Runner = Callable[[np.ndarray, np.ndarray], Any]

#: Post-processing shared by the OpenCV SGBM entries (OpenCV's sample values; speckleRange is in
#: pixels, OpenCV multiplies it by 16 internally).
OPENCV_COMMON: dict[str, int] = {
    "preFilterCap": 63,
    "uniquenessRatio": 10,
    "speckleWindowSize": 100,
    "speckleRange": 2,
    "disp12MaxDiff": 1,
}


@dataclass(frozen=True)
class Setup:
    """The problem every method is given: disparity range, block size and thread count."""

    num_disparities: int
    min_disparity: int = 0
    block_size: int = 5
    threads: int = 1

    def __post_init__(self) -> None:
        if not isinstance(self.num_disparities, (int, np.integer)) or self.num_disparities <= 0 or self.num_disparities % 16:
            raise ValueError(f"`num_disparities` must be a positive multiple of 16, got {self.num_disparities!r}")
        if not isinstance(self.block_size, (int, np.integer)) or self.block_size < 1 or self.block_size % 2 == 0:
            raise ValueError(f"`block_size` must be a positive odd integer, got {self.block_size!r}")
        if not isinstance(self.threads, (int, np.integer)) or self.threads < 1:
            raise ValueError(f"`threads` must be an integer >= 1, got {self.threads!r}")


@dataclass(frozen=True)
class Method:
    """One entry of the comparison.

    Attributes
    ----------
    name : str
        Short unique name used in tables and figures.
    family : str
        ``"stereo_classic"``, ``"opencv"``, ``"peer"`` (benchmarks.peers) or ``"onnx"``.
    description : str
        What it is, with its settings, for the report.
    factory : callable or None
        ``factory(setup) -> Runner``; builds a runner (and its buffers/objects) for one problem.
    available : bool
        False when the module behind it is missing; ``reason`` then says why.
    params : dict
        The settings that do not depend on the problem (for the report's JSON).
    """

    name: str
    family: str
    description: str
    factory: Callable[[Setup], Runner] | None
    available: bool = True
    reason: str = ""
    params: dict[str, Any] = field(default_factory=dict)

    def prepare(self, setup: Setup) -> Runner:
        """A runner for ``setup``; raises RuntimeError when the method is not available."""
        if not self.available or self.factory is None:
            raise RuntimeError(f"method {self.name!r} is not available: {self.reason}")
        return self.factory(setup)


def output_views(out: Any, shape: tuple[int, int] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``(output, measured)`` of what a runner returned.

    ``output`` is the method's disparity as a user gets it (the dense and unknown-is-bad views score it);
    ``measured`` holds only the pixels the method measured, the rest NaN (the valid view scores it). A plain
    array is both.

    Parameters
    ----------
    out : (H, W) float array, ``(output, measured)`` tuple, or object with ``filled_disparity`` (the output) and
        ``disparity`` (the measured pixels), as a ``DisparityMap``
    shape : (H, W), optional
        The shape both must have (the input's).

    Raises
    ------
    RuntimeError
        Anything else, arrays of another shape, or a measured pixel that the output leaves unknown.

    >>> import numpy as np
    >>> out = np.array([[1.0, 2.0]], np.float32)
    >>> output_views(out)[1] is out
    True
    >>> output_views((out, np.array([[1.0, np.nan]], np.float32)))[1].tolist()
    [[1.0, nan]]
    """
    if isinstance(out, np.ndarray):
        disp, measured = out, out
    elif isinstance(out, tuple) and len(out) == 2:
        disp, measured = out
    elif hasattr(out, "disparity") and hasattr(out, "filled_disparity"):
        disp, measured = out.filled_disparity, out.disparity  # the dense view needs the filled map
    else:
        raise RuntimeError(f"a method must return an (H, W) float array, an (output, measured) tuple or a DisparityMap, "
                           f"got {type(out).__name__}")
    want = tuple(shape) if shape is not None else getattr(disp, "shape", None)
    for label, arr in (("output", disp), ("measured", measured)):
        if not isinstance(arr, np.ndarray) or arr.shape != want or not np.issubdtype(arr.dtype, np.floating):
            raise RuntimeError(f"the method's {label} must be a float array of shape {want}, got {type(arr).__name__} "
                               f"of shape {getattr(arr, 'shape', None)} and dtype {getattr(arr, 'dtype', None)}")
    if measured is not disp and (np.isfinite(measured) & ~np.isfinite(disp)).any():
        raise RuntimeError("the method's measured disparity has values where its output is unknown")
    return disp, measured


def opencv_to_disparity(raw: np.ndarray, min_disparity: int) -> np.ndarray:
    """OpenCV's int16 fixed-point disparity (x16) to float32 pixels, NaN below ``min_disparity``."""
    disp = raw.astype(np.float32) / 16.0
    disp[disp < min_disparity] = np.nan
    return disp


def _channels(image: np.ndarray) -> int:
    return 1 if image.ndim == 2 else int(image.shape[2])


def _grey(image: np.ndarray) -> np.ndarray:
    if image.ndim == 2:
        return image
    return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)


def timing_pair(left: np.ndarray, right: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pair the speed tables time the classical methods on: grey (a grey pair is returned as it is).

    This matcher and Pandora read grey whatever they are given; OpenCV's StereoSGBM makes its matching cost from
    every channel of a colour pair (1.3-1.4x its grey time for MODE_SGBM_3WAY on the KITTI pair). Timed on grey,
    every method does the same work, and OpenCV runs at its fastest.
    """
    return _grey(left), _grey(right)


def _sgbm_factory(mode: int, *, fixed_block: int | None = None, fixed_p: tuple[int, int] | None = None) -> Callable[[Setup], Runner]:
    def factory(setup: Setup) -> Runner:
        block = fixed_block if fixed_block is not None else setup.block_size
        state: dict[str, Any] = {}

        def run(left: np.ndarray, right: np.ndarray) -> np.ndarray:
            cn = _channels(left)
            if state.get("cn") != cn:
                p1, p2 = fixed_p if fixed_p is not None else (8 * cn * block * block, 32 * cn * block * block)
                state["cn"] = cn
                state["matcher"] = cv2.StereoSGBM_create(
                    minDisparity=setup.min_disparity,
                    numDisparities=setup.num_disparities,
                    blockSize=block,
                    P1=p1,
                    P2=p2,
                    mode=mode,
                    **OPENCV_COMMON,
                )
            cv2.setNumThreads(setup.threads)
            raw = state["matcher"].compute(left, right)
            return opencv_to_disparity(raw, setup.min_disparity)

        return run

    return factory


def _bm_factory(setup: Setup) -> Runner:
    block = max(5, setup.block_size)
    matcher = cv2.StereoBM_create(numDisparities=setup.num_disparities, blockSize=block)
    matcher.setMinDisparity(setup.min_disparity)
    matcher.setUniquenessRatio(OPENCV_COMMON["uniquenessRatio"])
    matcher.setSpeckleWindowSize(OPENCV_COMMON["speckleWindowSize"])
    matcher.setSpeckleRange(OPENCV_COMMON["speckleRange"])
    matcher.setDisp12MaxDiff(OPENCV_COMMON["disp12MaxDiff"])

    def run(left: np.ndarray, right: np.ndarray) -> np.ndarray:
        cv2.setNumThreads(setup.threads)
        raw = matcher.compute(_grey(left), _grey(right))
        return opencv_to_disparity(raw, setup.min_disparity)

    return run


def opencv_methods() -> list[Method]:
    """OpenCV StereoSGBM in its four modes with the documented P1/P2, the KITTI OCV-SGBM settings, StereoBM."""
    doc = "P1 = 8*cn*block^2, P2 = 32*cn*block^2 (OpenCV docs)"
    modes = [
        ("ocv-sgbm", cv2.STEREO_SGBM_MODE_SGBM, "StereoSGBM MODE_SGBM (5 paths)"),
        ("ocv-hh", cv2.STEREO_SGBM_MODE_HH, "StereoSGBM MODE_HH (8 paths, full-image)"),
        ("ocv-3way", cv2.STEREO_SGBM_MODE_SGBM_3WAY, "StereoSGBM MODE_SGBM_3WAY (3 paths)"),
        ("ocv-hh4", cv2.STEREO_SGBM_MODE_HH4, "StereoSGBM MODE_HH4 (4 paths)"),
    ]
    out = [
        Method(name, "opencv", f"{desc}; {doc}", _sgbm_factory(mode), params={"mode": desc, "P1/P2": doc, **OPENCV_COMMON})
        for name, mode, desc in modes
    ]
    out.append(
        Method(
            "ocv-kitti",
            "opencv",
            "StereoSGBM MODE_HH with the KITTI 2015 OCV-SGBM settings: block 3, P1 36, P2 288, 8 paths",
            _sgbm_factory(cv2.STEREO_SGBM_MODE_HH, fixed_block=3, fixed_p=(36, 288)),
            params={"mode": "MODE_HH", "blockSize": 3, "P1": 36, "P2": 288, **OPENCV_COMMON},
        )
    )
    out.append(
        Method(
            "ocv-bm",
            "opencv",
            "StereoBM (block matching, grey input, no smoothness term): the floor",
            _bm_factory,
            params={k: v for k, v in OPENCV_COMMON.items() if k != "preFilterCap"},
        )
    )
    return out


#: (name, overrides of SGMParams(), what it is) of the matcher variants; short: every one runs on every scene.
_MATCHER_VARIANTS: tuple[tuple[str, dict[str, Any], str], ...] = (
    ("sc-default", {}, "stereo_classic SGMParams() defaults"),
    ("sc-mccnn", {"cost": "mccnn"},
     "the default with the learned cost of the shipped MC-CNN fast network, census in equal parts"),
    ("sc-mccnn-net", {"cost": "mccnn", "feature_census": 0.0},
     "sc-mccnn without its census share: the network alone (sc-mccnn before the census share)"),
    ("sc-mccnn-int8", {"cost": "mccnn", "feature_model": "mccnn-fast-int8"},
     "sc-mccnn with the paper's fast network in int8 (the other shipped one: about twice the time)"),
    ("sc-census-8", {"cost": "census", "paths": 8, "lr_check": None, "fill_holes": False},
     "the previous default (before commit cfc357c)"),
    ("sc-census-3", {"cost": "census"}, "the default with the plain census cost"),
    ("sc-8", {"paths": 8}, "the default with 8 paths"),
    ("sc-independent", {"lr_mode": "independent"},
     "the default with the left-right check against the right image's own match (the pair matched again, mirrored; "
     "1.5-1.9x the default's time)"),
    ("sc-sad-8", {"cost": "sad", "paths": 8, "lr_check": None, "fill_holes": False},
     "the like-for-like with OpenCV (SAD-style cost, 8 paths like MODE_HH, no fill)"),
)


def _settings(params: Any) -> str:
    return (f"cost {params.cost}, {params.paths} paths, LR check "
            f"{'off' if params.lr_check is None else f'{params.lr_check:g} px'}, "
            f"holes {'filled' if params.fill_holes else 'left unknown'}")


def _matcher_factory(overrides: dict[str, Any]) -> Callable[[Setup], Runner]:
    import stereo_classic as sc

    def factory(setup: Setup) -> Runner:
        params = sc.SGMParams(**overrides, num_disparities=setup.num_disparities,
                              min_disparity=setup.min_disparity, block_size=setup.block_size,
                              threads=setup.threads)
        matcher = sc.StereoMatcher(params)

        def run(left: np.ndarray, right: np.ndarray) -> Any:
            return matcher.compute(left, right)  # a DisparityMap: output and measured pixels (output_views)

        return run

    return factory


def stereo_classic_methods() -> list[Method]:
    """This project's matcher: the default and the variants of :data:`_MATCHER_VARIANTS`."""
    import stereo_classic as sc

    out = []
    for name, overrides, desc in _MATCHER_VARIANTS:
        defaults = sc.SGMParams(**overrides)
        shown = {f.name: getattr(defaults, f.name) for f in sorted(dataclasses.fields(defaults), key=lambda f: f.name)
                 if f.name not in ("num_disparities", "min_disparity")}
        shown = {k: (v if isinstance(v, (int, float, str, bool, type(None))) else repr(v)) for k, v in shown.items()}
        out.append(Method(name, "stereo_classic", f"{desc} ({_settings(defaults)})", _matcher_factory(overrides),
                          params=shown))
    return out


def peer_methods() -> list[Method]:
    """The accuracy peers outside OpenCV (``benchmarks.peers``; the extra ``.[peers]``): ``pandora``."""
    ok, reason = peers.pandora_available()
    return [Method("pandora", "peer", peers.PANDORA_DESCRIPTION, peers.pandora_factory if ok else None, available=ok,
                   reason=reason, params={"steps": " -> ".join(peers.PANDORA_PIPELINE), "P1/P2": "8/32", "census": "5x5",
                           "threads": "1 (single-threaded)", "versions": "pandora 1.9.0, pandora-plugin-libsgm 1.5.8"})]


def default_methods(names: Sequence[str] | None = None) -> list[Method]:
    """All built-in methods (matcher variants first, then OpenCV, then the peers of ``benchmarks.peers``), optionally
    filtered by name. A peer whose extra is missing is listed as not available (its reason says how to install it)."""
    methods = stereo_classic_methods() + opencv_methods() + peer_methods()
    if names:
        known = {m.name for m in methods}
        unknown = [n for n in names if n not in known]
        if unknown:
            raise ValueError(f"`methods` must be names from {sorted(known)}, got unknown {unknown}")
        methods = [m for m in methods if m.name in names]
    return methods
