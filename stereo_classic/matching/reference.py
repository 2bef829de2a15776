"""Slow, obvious numpy reference of the SGM matcher, for the tests of the numba kernels.

Everything here is written for clarity, not speed (pixel or row loops in Python, int64 arithmetic):
the census transform and both matching costs, one path's recursion for any of the 8 directions,
and the winner selection (WTA, uniqueness, subpixel, right view, left-right check). Conventions are
those of the kernels (``_kernels/core.py``): entry ``[y, x, k]`` is disparity ``min_disparity + k``,
i.e. the left pixel ``x`` against the right pixel ``x - min_disparity - k``.
"""

from __future__ import annotations

import numpy as np

from stereo_classic.matching._kernels.core import PATH_STEPS, cost_scale

__all__ = ["census_reference", "cost_volume_reference", "feature_cost_reference", "path_reference", "sum_reference", "select_reference"]


def census_reference(image: np.ndarray, census_window: tuple[int, int]) -> np.ndarray:
    """(H, W) uint64: one bit per window pixel except the centre, set where it is darker than the
    centre; image borders replicated."""
    w, h = census_window
    H, W = image.shape
    img = image.astype(np.int64)
    code = np.zeros((H, W), np.uint64)
    ys = np.arange(H)[:, None]
    xs = np.arange(W)[None, :]
    for dy in range(-(h // 2), h // 2 + 1):
        for dx in range(-(w // 2), w // 2 + 1):
            if dy == 0 and dx == 0:
                continue
            nb = img[np.clip(ys + dy, 0, H - 1), np.clip(xs + dx, 0, W - 1)]
            code = (code << np.uint64(1)) | (nb < img).astype(np.uint64)
    return code


def _sobel_reference(image: np.ndarray) -> np.ndarray:
    img = image.astype(np.int64)
    H, W = img.shape
    out = np.zeros((H, W), np.int64)
    for y in range(H):
        for x in range(W):
            def at(yy, xx):
                return img[min(max(yy, 0), H - 1), min(max(xx, 0), W - 1)]
            g = ((at(y - 1, x + 1) - at(y - 1, x - 1)) + 2 * (at(y, x + 1) - at(y, x - 1))
                 + (at(y + 1, x + 1) - at(y + 1, x - 1)))
            out[y, x] = min(max(g, -31), 31) + 31
    return out


def feature_cost_reference(left_features, right_features, *, similarity="dot", min_disparity=0, num_disparities=16,
                           p2=120, census_share=0.0, images=None, census_window=(9, 7)) -> np.ndarray:
    """(H, W, D) int64 learned cost from (H, C, W) int8 unit features (``learned.FeatureModel.features``):
    ``s * FEATURE_SCALE * (1 - sum(qL * qR) / FEATURE_QUANT**2)`` (dot) or ``s * FEATURE_SCALE * sum|qL - qR| /
    (FEATURE_QUANT * sqrt(C))`` (L1), ``s = 1 - census_share``, rounded half up and clipped to [0, 2 * FEATURE_SCALE];
    with a ``census_share`` > 0 plus ``(h * m + 128) >> 8``, ``h`` the Hamming distance of the census codes of
    ``images`` (the (left, right) grey pair), ``m = round(256 * census_share * 2 * FEATURE_SCALE / bits)``, at most
    ``2 * FEATURE_SCALE`` in all; a match outside the right image costs ``FEATURE_OUTSIDE`` (``p2`` is not used:
    kept for the callers)."""
    from stereo_classic.matching._kernels.features import FEATURE_OUTSIDE, FEATURE_QUANT, FEATURE_SCALE

    H, C, W = left_features.shape
    D = num_disparities
    cmax = 2 * FEATURE_SCALE
    own = 1.0 - census_share
    out = np.full((H, W, D), FEATURE_OUTSIDE, np.int64)
    fl = left_features.astype(np.int64)
    fr = right_features.astype(np.int64)
    if census_share > 0:
        codes = [census_reference(img, census_window) for img in images]
        bits = census_window[0] * census_window[1] - 1
        m = int(round(256 * census_share * 2 * FEATURE_SCALE / bits))
    for k in range(D):
        d = min_disparity + k
        for x in range(W):
            xr = x - d
            if not 0 <= xr < W:
                continue
            if similarity == "dot":
                acc = (fl[:, :, x] * fr[:, :, xr]).sum(axis=1)
                v = own * FEATURE_SCALE + 0.5 - acc * (own * FEATURE_SCALE / FEATURE_QUANT**2)
            else:
                acc = np.abs(fl[:, :, x] - fr[:, :, xr]).sum(axis=1)
                v = 0.5 + acc * (own * FEATURE_SCALE / (FEATURE_QUANT * np.sqrt(C)))
            cost = np.floor(np.clip(v, 0, cmax)).astype(np.int64)
            if census_share > 0:
                ham = np.array([bin(int(a) ^ int(b)).count("1") for a, b in zip(codes[0][:, x], codes[1][:, xr])])
                cost = np.minimum(cost + ((ham * m + 128) >> 8), cmax)
            out[:, x, k] = cost
    return out


def cost_volume_reference(left, right, *, cost="census", min_disparity=0, num_disparities=16, block_size=5,
                          census_window=(9, 7), p2=120, outside_cost=None) -> np.ndarray:
    """(H, W, D) int64 cost, invalid disparities (match outside the right image) = cmax + 2*p2s + 1, or
    ``min(outside_cost >> shift, cmax)`` when given."""
    H, W = left.shape
    D = num_disparities
    shift, cmax = cost_scale(cost, block_size, census_window, p2)
    cinv = cmax + 2 * (p2 >> shift) + 1 if outside_cost is None else min(int(outside_cost) >> shift, cmax)
    out = np.full((H, W, D), cinv, np.int64)
    if cost == "census":
        cl = census_reference(left, census_window)
        cr = census_reference(right, census_window)
        for y in range(H):
            for x in range(W):
                for k in range(D):
                    xr = x - min_disparity - k
                    if 0 <= xr < W:
                        out[y, x, k] = bin(int(cl[y, x]) ^ int(cr[y, xr])).count("1")
        return out
    if cost == "census+grad":  # census + the window mean of |sobel_L - sobel_R| (no intensity term)
        census = cost_volume_reference(left, right, cost="census", min_disparity=min_disparity,
                                       num_disparities=num_disparities, census_window=census_window, p2=p2,
                                       outside_cost=outside_cost)
        sums = _window_sums(left, right, min_disparity, D, block_size, intensity=False)
        mul = round(1024 / (block_size * block_size))
        return np.where(sums >= 0, census + ((sums * mul) >> 10), out)
    sums = _window_sums(left, right, min_disparity, D, block_size, intensity=True)
    return np.where(sums >= 0, np.minimum(sums >> shift, cmax), out)


def _window_sums(left, right, min_disparity, D, block_size, *, intensity) -> np.ndarray:
    """(H, W, D) int64 window sums of ``|sobel_L - sobel_R|`` (+ ``|I_L - I_R| // 4`` with ``intensity``), borders
    replicated; -1 where the match lies outside the right image."""
    H, W = left.shape
    sl, sr = _sobel_reference(left), _sobel_reference(right)
    il, ir = left.astype(np.int64), right.astype(np.int64)
    r = block_size // 2

    def cy(v):
        return min(max(v, 0), H - 1)

    def cx(v):
        return min(max(v, 0), W - 1)

    out = np.full((H, W, D), -1, np.int64)
    for y in range(H):
        for x in range(W):
            for k in range(D):
                xr = x - min_disparity - k
                if not 0 <= xr < W:
                    continue
                total = 0
                for dy in range(-r, r + 1):
                    for dx in range(-r, r + 1):
                        yy, xl, xrr = cy(y + dy), cx(x + dx), cx(xr + dx)
                        total += abs(sl[yy, xl] - sr[yy, xrr])
                        if intensity:
                            total += abs(il[yy, xl] - ir[yy, xrr]) // 4
                out[y, x, k] = total
    return out


def path_reference(C: np.ndarray, direction: int, p1: int, p2: int, image: np.ndarray | None = None,
                   scale: np.ndarray | None = None, *, p1_cross: int | None = None,
                   cross_texture: bool = True) -> np.ndarray:
    """L_r for one direction (index into ``_kernels.core.PATH_STEPS``), int64 (H, W, D).

    L(p, d) = C(p, d) + min(L(p-r, d), L(p-r, d-1) + P1, L(p-r, d+1) + P1, min_k L(p-r, k) + P2)
              - min_k L(p-r, k),   and L(p) = C(p) where p - r is outside the image.
    A direction that crosses rows (dy != 0) uses ``p1_cross`` (None: ``p1``) as P1.
    With ``scale`` ((H, W) sixteenths, ``weak_texture_scale``) the penalties at p are (P * scale(p) + 8) >> 4, P1 of
    a direction that crosses rows only with ``cross_texture``.
    With ``image`` given, P2 is adaptive: max(P1, P2 // (1 + |I(p) - I(p-r)|)) (of p's penalties).
    """
    H, W, D = C.shape
    dx, dy = PATH_STEPS[direction]
    crosses = dy != 0
    if crosses and p1_cross is not None:
        p1 = p1_cross
    L = np.zeros((H, W, D), np.int64)
    ys = range(H) if dy >= 0 else range(H - 1, -1, -1)
    xs = list(range(W)) if dx >= 0 else list(range(W - 1, -1, -1))
    big = 1 << 40
    for y in ys:
        for x in xs:
            yp, xp = y - dy, x - dx
            if not (0 <= yp < H and 0 <= xp < W):
                L[y, x] = C[y, x]
                continue
            prev = L[yp, xp]
            mp = prev.min()
            p1e, p2e = p1, p2
            if scale is not None:
                p2e = (p2 * int(scale[y, x]) + 8) >> 4
                if cross_texture or not crosses:
                    p1e = (p1 * int(scale[y, x]) + 8) >> 4
            if image is not None:
                p2e = max(p1e, p2e // (1 + abs(int(image[y, x]) - int(image[yp, xp]))))
            best = np.minimum(prev, mp + p2e)
            lower = np.concatenate([[big], prev[:-1]]) + p1e
            upper = np.concatenate([prev[1:], [big]]) + p1e
            best = np.minimum(best, np.minimum(lower, upper))
            L[y, x] = C[y, x] + best - mp
    return L


def sum_reference(C: np.ndarray, path_mask: int, p1: int, p2: int, image: np.ndarray | None = None,
                  scale: np.ndarray | None = None, *, p1_cross: int | None = None,
                  cross_texture: bool = True) -> np.ndarray:
    """Sum of path_reference over the directions whose bit is set in path_mask."""
    S = np.zeros(C.shape, np.int64)
    for r in range(8):
        if path_mask >> r & 1:
            S += path_reference(C, r, p1, p2, image, scale, p1_cross=p1_cross, cross_texture=cross_texture)
    return S


def select_reference(S: np.ndarray, min_disparity: int, *, uniqueness=0.0, lr_check=1.0, subpixel=True,
                     lr_mode="full"):
    """(disparity, disparity_right) float32 from a complete sum volume, pixel by pixel.

    Valid disparities of left pixel x: indices k with 0 <= x - min_disparity - k < W. Winner = first
    index of the minimum over all k; when it is not valid (a neutral cost of a match outside the image won) the
    pixel is unknown; uniqueness rejects when some valid k with |k - best| >= 2 has
    S * (1 - uniqueness) < S_best; subpixel: parabola through best - 1, best, best + 1 when both are
    valid and the curvature is positive.

    LR check, lr_mode "full": reject when |best - right_best(x - dmin - best)| > lr_check, right_best
    being the right view below.

    LR check, lr_mode "opencv" (OpenCV StereoSGBM's): going through x from right to left, every left pixel that passed
    uniqueness claims the right pixel x - dmin - best when its minimum sum is strictly lower than
    the claim there so far. A left pixel is rejected when, for both k = floor(d - dmin) and
    k = ceil(d - dmin) of its (subpixel) disparity d, the right pixel x - dmin - k is claimed with
    a disparity index differing from k by more than lr_check.

    Right view (returned for comparison with ``return_right=True``): for right pixel xr, argmin
    over k of S[y, xr + min_disparity + k, k] (first k on ties).
    """
    H, W, D = S.shape
    dmin = min_disparity
    disp = np.full((H, W), np.nan, np.float32)
    dispR = np.full((H, W), np.nan, np.float32)
    for y in range(H):
        for xr in range(W):
            cands = [(int(S[y, xr + dmin + k, k]), k) for k in range(D) if 0 <= xr + dmin + k < W]
            if cands:
                dispR[y, xr] = dmin + min(cands)[1]
        best = {}
        for x in range(W):
            valid = [k for k in range(D) if 0 <= x - dmin - k < W]
            if not valid:
                continue
            every = [int(S[y, x, k]) for k in range(D)]
            m = min(every)
            b = every.index(m)
            if b not in valid:  # the match is outside the right image: not a measurement
                continue
            if uniqueness > 0:
                far = [int(S[y, x, k]) for k in valid if abs(k - b) >= 2]
                if far and float(min(far)) * (1.0 - uniqueness) < float(m):
                    continue
            off = 0.0
            if subpixel and (b - 1) in valid and (b + 1) in valid:
                sm, sp = int(S[y, x, b - 1]), int(S[y, x, b + 1])
                den = sm + sp - 2 * m
                if den > 0:
                    off = (sm - sp) / (2.0 * den)
            disp[y, x] = np.float32(dmin + b + off)
            best[x] = (b, m)
        if lr_check is None:
            continue
        if lr_mode == "full":
            for x, (b, _) in best.items():
                xr = x - dmin - b
                if abs(b - (int(dispR[y, xr]) - dmin)) > lr_check:
                    disp[y, x] = np.nan
            continue
        claim_cost = [None] * W
        claim_k = [-1] * W
        for x in range(W - 1, -1, -1):
            if x in best:
                b, m = best[x]
                xr = x - dmin - b
                if claim_cost[xr] is None or m < claim_cost[xr]:
                    claim_cost[xr], claim_k[xr] = m, b
        for x in best:
            t = float(disp[y, x]) - dmin
            fails = []
            for k in (int(np.floor(t)), int(np.ceil(t))):
                xr = x - dmin - k
                fails.append(0 <= xr < W and claim_k[xr] >= 0 and abs(claim_k[xr] - k) > lr_check)
            if all(fails):
                disp[y, x] = np.nan
    return disp, dispR
