"""The speckle filter's connected components in horizontal stripes (numba), so that it runs on every thread.

``cv2.filterSpeckles`` floods one region after another on one thread; at 1242x375 it took 4.4 ms of the 10 ms of
serial post-processing after a 2-thread match. Regions here are the same (4-connected pixels whose scaled
int16 values differ by at most ``max_diff``; a region of at most ``max_size`` pixels is removed), found in
three steps:

1. ``label_stripe`` (one call per stripe, in parallel): scales the stripe's rows to int16 like the caller
   asked, labels its pixels with a union-find over the stripe's own label range (labels of stripe ``s`` start
   at ``y0 * W``, so no two stripes share one) and counts each region's pixels.
2. ``join_stripes`` (serial, ``W`` pixels per stripe border): joins the regions that touch across a border and
   adds up their sizes.
3. ``apply_stripe`` (in parallel): each pixel of a region of at most ``max_size`` pixels becomes NaN, as does
   every pixel that was not finite; it returns the number of pixels kept. ``apply_and_fill_stripe`` does this
   and the hole fill of :func:`stereo_classic.matching.postprocess.fill_holes` in the same pass (what the matcher
   runs when both are on): no filtered map, row fill or median image is stored between the two.

Connected components do not depend on the order they are found in: the result is the same for any stripes
and any thread count, and equal to ``cv2.filterSpeckles`` (tested pixel for pixel).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["apply_and_fill_stripe", "apply_stripe", "join_stripes", "label_stripe"]


@njit(cache=True, nogil=True, inline="always")
def _root(parent, i):  # pragma: no cover - numba
    while parent[i] != i:
        i = parent[i]
    return i


@njit(cache=True, nogil=True)
def label_stripe(disp, scale, max_diff, y0, y1, scaled, labels, parent, sizes):  # pragma: no cover - numba
    """Label rows [y0, y1): ``scaled`` = rint(disp * scale) as int16 (float32 arithmetic, ties to even) where
    finite; ``labels`` = a region label (``-1`` where not finite); ``parent`` = every label's root (the smallest
    label of its region within the stripe); ``sizes`` = each root's pixel count. Labels are ``y0 * W + k``.

    A row goes in runs of pixels joined to their left neighbour, whose region's root is carried along (no root
    lookup per pixel); a run looks a label of the row above up only where it differs from the one it last joined,
    and counts its pixels in a register (a count in memory per pixel is a chain of loads and stores on one
    address)."""
    W = disp.shape[1]
    base = y0 * W
    n = 0
    for y in range(y0, y1):
        drow = disp[y]
        srow = scaled[y]
        lrow = labels[y]
        above = y > y0
        urow = labels[y - 1] if above else lrow
        usrow = scaled[y - 1] if above else srow
        a = -1  # root of the region of the run the pixel continues (-1: none)
        seen_up = -1  # the label above that the run last joined
        count = 0  # pixels of the run not yet added to sizes[counted]
        counted = 0
        prev = np.int32(0)
        for x in range(W):
            v = drow[x]
            if not np.isfinite(v):
                if count > 0:
                    sizes[counted] += count
                    count = 0
                lrow[x] = -1
                a = -1
                seen_up = -1
                continue
            sv = np.int16(np.rint(v * scale))
            srow[x] = sv
            si = np.int32(sv)
            if a >= 0 and abs(si - prev) > max_diff:  # the run ends
                sizes[counted] += count
                count = 0
                a = -1
                seen_up = -1
            prev = si
            if above:
                u = urow[x]
                if u >= 0 and u != seen_up and abs(si - np.int32(usrow[x])) <= max_diff:
                    b = _root(parent, u)
                    if a < 0:
                        a = b
                        counted = b
                    elif b != a:  # two regions meet: the larger root joins the smaller
                        lo_r = min(a, b)
                        parent[max(a, b)] = lo_r
                        a = lo_r
                    seen_up = u
            if a < 0:
                a = base + n
                parent[a] = a
                sizes[a] = 0
                n += 1
                counted = a
            lrow[x] = a
            count += 1
        if count > 0:
            sizes[counted] += count
    # every label's parent is smaller than itself: in increasing order, each one's parent is already a root
    for k in range(base, base + n):
        p = parent[k]
        if p != k:
            r = parent[p]
            parent[k] = r
            sizes[r] += sizes[k]
            sizes[k] = 0
    return n


@njit(cache=True, nogil=True)
def join_stripes(starts, max_diff, scaled, labels, parent, sizes):  # pragma: no cover - numba
    """Join the regions that touch across the border above each row of ``starts`` (the stripes' first rows but
    the first), adding their sizes at the joined root; then point every border label straight at its root."""
    W = labels.shape[1]
    for y in starts:
        for x in range(W):
            a = labels[y - 1, x]
            b = labels[y, x]
            if a < 0 or b < 0 or abs(np.int32(scaled[y, x]) - np.int32(scaled[y - 1, x])) > max_diff:
                continue
            ra = _root(parent, a)
            rb = _root(parent, b)
            if ra != rb:
                lo_r = min(ra, rb)
                hi_r = max(ra, rb)
                parent[hi_r] = lo_r
                sizes[lo_r] += sizes[hi_r]
    for y in starts:
        for dy in range(2):
            for x in range(W):
                a = labels[y - dy, x]
                if a >= 0:
                    parent[parent[a]] = _root(parent, a)


@njit(cache=True, nogil=True)
def apply_stripe(disp, max_size, y0, y1, labels, parent, sizes, out):  # pragma: no cover - numba
    """``out`` = ``disp`` in rows [y0, y1), NaN where not finite or in a region of at most ``max_size`` pixels;
    returns how many pixels it kept."""
    W = disp.shape[1]
    nan = np.float32(np.nan)
    kept = 0
    for y in range(y0, y1):
        last = -1  # a row's pixels come in runs of one label: look its region up once per run
        keep = False
        for x in range(W):
            a = labels[y, x]
            if a != last:
                last = a
                keep = a >= 0 and sizes[_root(parent, a)] > max_size
            if keep:
                out[y, x] = disp[y, x]
                kept += 1
            else:
                out[y, x] = nan
    return kept


@njit(cache=True, nogil=True)
def _filled_row(disp, max_size, y, labels, parent, sizes, frow, krow):  # pragma: no cover - numba
    """Row ``y`` after the speckle filter (``krow`` = 1 where a pixel is kept) and its background fill: ``frow`` =
    the kept value, else the smaller of the nearest kept values to its left and right (the one that exists);
    0 everywhere when the row keeps no pixel. Returns how many pixels the row keeps."""
    W = disp.shape[1]
    inf = np.float32(np.inf)
    last_label = -1
    keep = False
    last = inf
    n = 0
    for x in range(W):  # the filter, and the left neighbour
        a = labels[y, x]
        if a != last_label:
            last_label = a
            keep = a >= 0 and sizes[_root(parent, a)] > max_size
        if keep:
            last = disp[y, x]
            n += 1
        krow[x] = keep
        frow[x] = last
    if n == 0:
        frow[:] = np.float32(0.0)
        return 0
    nxt = inf
    for x in range(W - 1, -1, -1):  # the right neighbour: the smaller of the two
        if krow[x]:
            nxt = frow[x]
        elif nxt < frow[x]:
            frow[x] = nxt
    return n


@njit(cache=True, nogil=True, inline="always")
def _med3(a, b, c):  # pragma: no cover - numba
    return max(min(a, b), min(max(a, b), c))


@njit(cache=True, nogil=True)
def apply_and_fill_stripe(disp, max_size, y0, y1, labels, parent, sizes, out, holes, measured, rows, kept_rows,
                          columns):  # pragma: no cover - numba
    """Rows [y0, y1) of ``fill_holes_marked(filter_speckles(disp))``: the speckle filter (as ``apply_stripe``),
    then each unknown pixel takes the smaller of the nearest known values to its left and right in its row, and
    then the 3x3 median (borders replicated) of that row-filled map; where a row without any known pixel is
    among the 3 rows, the row fill itself; in a row without any known pixel, NaN. ``holes`` = the pixels filled;
    ``measured`` = the filtered map (``out`` with NaN where filled: ``DisparityMap.disparity``).

    ``rows`` (3, W) float32, ``kept_rows`` (3, W) uint8 and ``columns`` (3, W + 2) float32 are this worker's
    scratch: the row-filled rows y - 1, y, y + 1 in a ring (row r in slot r % 3; a stripe makes its border rows'
    neighbours itself, reading only the labels), and the sorted columns of the three. The median of 3 x 3 values
    is the median of (the largest of the columns' smallest, the median of their medians, the smallest of their
    largest): exact, without branches. Returns (pixels kept by the filter, pixels filled)."""
    H, W = disp.shape
    nan = np.float32(np.nan)
    n_kept = 0
    n_filled = 0
    known = np.zeros(3, np.int64)  # pixels each ring row keeps (0: a row without any known pixel)
    lo, mi, hi = columns[0], columns[1], columns[2]
    for r in range(max(0, y0 - 1), min(H, y0 + 1)):
        known[r % 3] = _filled_row(disp, max_size, r, labels, parent, sizes, rows[r % 3], kept_rows[r % 3])
    for y in range(y0, y1):
        if y + 1 < H:
            known[(y + 1) % 3] = _filled_row(disp, max_size, y + 1, labels, parent, sizes, rows[(y + 1) % 3],
                                             kept_rows[(y + 1) % 3])
        s = y % 3
        sm = max(y - 1, 0) % 3
        sp = min(y + 1, H - 1) % 3
        kept = kept_rows[s]
        if known[s] == 0:
            for x in range(W):
                out[y, x] = nan
                holes[y, x] = False
                measured[y, x] = nan
            continue
        n_kept += known[s]
        n_filled += W - known[s]
        b = rows[s]
        if known[sm] == 0 or known[sp] == 0:  # the median would see a row without any known pixel: the row fill
            for x in range(W):
                out[y, x] = disp[y, x] if kept[x] else b[x]
                holes[y, x] = not kept[x]
                measured[y, x] = disp[y, x] if kept[x] else nan
            continue
        a, c = rows[sm], rows[sp]
        for x in range(W):
            u, v, w = a[x], b[x], c[x]
            lo[x + 1] = min(min(u, v), w)
            hi[x + 1] = max(max(u, v), w)
            mi[x + 1] = _med3(u, v, w)
        lo[0], mi[0], hi[0] = lo[1], mi[1], hi[1]  # borders replicated: column -1 is column 0, column W is W - 1
        lo[W + 1], mi[W + 1], hi[W + 1] = lo[W], mi[W], hi[W]
        drow = disp[y]
        orow = out[y]
        hrow = holes[y]
        mrow = measured[y]
        for x in range(W):  # column x of the image is x + 1 of the sorted thirds: no clamped index, vector loads
            m = _med3(max(max(lo[x], lo[x + 1]), lo[x + 2]), _med3(mi[x], mi[x + 1], mi[x + 2]),
                      min(min(hi[x], hi[x + 1]), hi[x + 2]))
            k = kept[x] != 0
            orow[x] = drow[x] if k else m
            hrow[x] = not k
            mrow[x] = drow[x] if k else nan
    return n_kept, n_filled
