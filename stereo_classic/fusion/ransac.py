"""1-D RANSAC over disparities: the heaviest consistent set, its growth over continuous values, and
sequential RANSAC for several sets.

Every function works on *sorted* values, so the support of a band is a difference of a cumulative sum
found with ``searchsorted`` (O(log n) per hypothesis, vectorised and exact), and a consistent set is a
run ``s[lo:hi]`` of the sorted values.
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from stereo_classic.fusion.params import FusionInputError, as_generator, check_count, check_positive_float

__all__ = ["ransac_1d", "Cluster", "sequential_clusters"]


class Cluster(NamedTuple):
    """One consistent set found by :func:`sequential_clusters`.

    Attributes
    ----------
    support : float
        Summed weight of the members.
    centre : float
        Weighted mean of the members' values (pixels of disparity).
    mask : (n,) bool
        Members among the input values.
    low, high : float
        Limits of the set's (grown) band, same unit as the values.
    """

    support: float
    centre: float
    mask: np.ndarray
    low: float
    high: float


def ransac_1d(
    values: np.ndarray,
    tolerance: float,
    *,
    weights: np.ndarray | None = None,
    max_iterations: int = 256,
    rng: Any = None,
) -> tuple[float, np.ndarray]:
    """Find the heaviest set of 1-D values that lie within ``tolerance`` of one centre.

    Parameters
    ----------
    values : (n,) float array
        Finite values (here: disparities in pixels).
    tolerance : float
        Half width of the inlier band, same unit as ``values``.
    weights : (n,) float array, optional
        Non-negative weight per value (default 1: the largest set).
    max_iterations : int >= 1
        Number of hypotheses; each is one of the values. When ``n <= max_iterations`` every value is a
        hypothesis (exhaustive and independent of ``rng``), otherwise ``max_iterations`` values are drawn
        without replacement with ``rng``.
    rng : None, int or numpy.random.Generator
        Seed for drawing hypotheses. ``None`` means seed 0: results are reproducible by default.

    Returns
    -------
    centre : float
        The refined centre (weighted mean of the inliers); NaN when ``values`` is empty.
    inliers : (n,) bool array
        ``centre - tolerance <= values <= centre + tolerance`` after refinement (the band's limits are
        computed in floating point once, and every comparison uses them).

    Notes
    -----
    Support is summed over a sorted copy with a cumulative sum and ``searchsorted`` (O(log n) per
    hypothesis), so it is vectorised and exact. Among hypotheses with the same support the largest value
    wins (in disparity: the nearer one). The winner is re-centred on the mean of its inliers while that
    does not lose support.

    Examples
    --------
    >>> c, m = ransac_1d(np.array([1.0, 1.1, 0.9, 5.0]), 0.5)
    >>> round(c, 3), int(m.sum())
    (1.0, 3)
    """
    tolerance = check_positive_float("tolerance", tolerance)
    check_count("max_iterations", max_iterations)
    try:
        v = np.asarray(values, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        raise FusionInputError(f"`values` must be an array of numbers, got {type(values).__name__}") from None
    if v.size == 0:
        return math.nan, np.zeros(0, dtype=bool)
    if not np.all(np.isfinite(v)):
        raise FusionInputError("`values` must all be finite")
    if weights is None:
        w = np.ones_like(v)
    else:
        w = np.asarray(weights, dtype=np.float64).ravel()
        if w.shape != v.shape or not np.all(np.isfinite(w)) or np.any(w < 0):
            raise FusionInputError(f"`weights` must be {v.size} finite non-negative numbers")
    gen = as_generator(rng)
    order = np.argsort(v, kind="stable")
    centre, _, _ = _ransac_sorted(v[order], w[order], tolerance, max_iterations, gen)
    return centre, (v >= centre - tolerance) & (v <= centre + tolerance)


def _ransac_sorted(s: np.ndarray, w: np.ndarray, tolerance: float, max_iterations: int,
                   gen: np.random.Generator) -> tuple[float, int, int]:
    """RANSAC core on sorted values ``s`` with weights ``w``: (centre, first, end) of the inlier run."""
    cw = np.concatenate([[0.0], np.cumsum(w)])

    def run(centre: float) -> tuple[int, int]:
        return (int(np.searchsorted(s, centre - tolerance, "left")),
                int(np.searchsorted(s, centre + tolerance, "right")))

    if s.size <= max_iterations:
        hyp = s
    else:
        hyp = s[np.sort(gen.choice(s.size, size=max_iterations, replace=False))]
    sup = cw[np.searchsorted(s, hyp + tolerance, "right")] - cw[np.searchsorted(s, hyp - tolerance, "left")]
    best = sup.max()
    centre = float(hyp[sup >= best * (1 - 1e-12)].max())  # tie -> nearer (larger disparity)
    lo, hi = run(centre)
    for _ in range(3):  # local refinement: re-centre on the inliers' mean while support does not drop
        ws = cw[hi] - cw[lo]
        mean = float(np.dot(s[lo:hi], w[lo:hi]) / ws) if ws > 0 else float(s[lo:hi].mean())
        nlo, nhi = run(mean)
        new = cw[nhi] - cw[nlo]
        if new < best or mean == centre:
            break
        centre, best, lo, hi = mean, new, nlo, nhi
    return centre, lo, hi


def _grow_sorted(s: np.ndarray, lo: int, hi: int, band: tuple[float, float], tolerance: float,
                 grow_density: float) -> tuple[int, int, tuple[float, float]]:
    """Extend a consistent run ``s[lo:hi]`` of sorted values (inside ``band``) over the values that continue
    it without a gap.

    The object's depths are continuous: starting from the RANSAC band, steps of ``tolerance`` are added
    on each side while each step holds at least ``grow_density`` times the band's mean number of values
    per step. A gap (a sparse step) stops the growth, so the background behind the object stays out.
    Returns the new run and the new band limits.
    """
    b_lo, b_hi = band
    if grow_density <= 0 or hi <= lo:
        return lo, hi, band
    need = max(1.0, grow_density * (hi - lo) * tolerance / (b_hi - b_lo))
    while True:  # upwards
        end = int(np.searchsorted(s, b_hi + tolerance, "right"))
        if end - hi < need:
            break
        hi, b_hi = end, b_hi + tolerance
    while True:  # downwards
        start = int(np.searchsorted(s, b_lo - tolerance, "left"))
        if lo - start < need:
            break
        lo, b_lo = start, b_lo - tolerance
    return lo, hi, (b_lo, b_hi)


def sequential_clusters(values: np.ndarray, weights: np.ndarray, tolerance: float, grow_density: float,
                        max_clusters: int, max_iterations: int, gen: np.random.Generator,
                        min_pixels: int) -> list[Cluster]:
    """Sequential RANSAC: up to ``max_clusters`` consistent sets, heaviest first.

    Values are sorted once; each set is a RANSAC band (:func:`ransac_1d`'s core) grown over continuous
    values, taken out of the remaining sorted values before the next round.

    Parameters
    ----------
    values : (n,) float64
        Finite values (disparities, pixels).
    weights : (n,) float64
        Non-negative vote of each value.
    tolerance : float > 0
        Half width of the RANSAC band, same unit as ``values``.
    grow_density : float in [0, 1]
        See ``FusionParams.grow_density`` (0: no growth).
    max_clusters, max_iterations : int >= 1
        Rounds of sequential RANSAC, hypotheses per round.
    gen : numpy.random.Generator
        Draws the hypotheses when there are more values than ``max_iterations``.
    min_pixels : int >= 1
        A round that finds fewer members (or starts with fewer remaining values) ends the search.

    Returns
    -------
    list of Cluster
        Sorted by support, then by centre, both descending (ties to the nearer set).

    Examples
    --------
    >>> v = np.array([1.0, 1.1, 0.9, 5.0, 5.1])
    >>> [round(c.centre, 2) for c in sequential_clusters(v, np.ones(5), 0.5, 0.0, 3, 256,
    ...                                                  np.random.default_rng(0), 2)]
    [1.0, 5.05]
    """
    order = np.argsort(values)  # ties need no order: a set is a band of values, equal values go together
    s_all, w_all = values[order], weights[order]
    remaining = np.ones(values.size, dtype=bool)
    out: list[Cluster] = []
    for _ in range(max_clusters):
        idx = np.flatnonzero(remaining)  # positions in the sorted arrays, still sorted
        if idx.size < min_pixels:
            break
        s, w = s_all[idx], w_all[idx]
        c, lo, hi = _ransac_sorted(s, w, tolerance, max_iterations, gen)
        lo, hi, band = _grow_sorted(s, lo, hi, (c - tolerance, c + tolerance), tolerance, grow_density)
        if hi - lo < min_pixels:
            break
        members = idx[lo:hi]
        ws = float(w[lo:hi].sum())
        centre = float(np.dot(s[lo:hi], w[lo:hi]) / ws) if ws > 0 else float(s[lo:hi].mean())
        mask = np.zeros(values.size, dtype=bool)
        mask[order[members]] = True
        out.append(Cluster(ws, centre, mask, band[0], band[1]))
        remaining[members] = False
    out.sort(key=lambda c: (-c.support, -c.centre))
    return out
