"""The whole-vector path updates (``_kernels.pathvec``) against the per-disparity loops they replace (``_lr``)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from numba import njit

from stereo_classic.matching._kernels import pathvec, vectors
from stereo_classic.matching._kernels.aggregate import _SENTINEL, _lr
from stereo_classic.matching._kernels.intrinsics import add16, umin16
from stereo_classic.matching._kernels.pathvec import (load_vector, right_path_sum, right_path_view, store_vector,
                                                      top_and_left, top_path, vector_of, vector_paths)
from stereo_classic.matching._kernels.rowpass import path_slots, slot_size
from stereo_classic.matching._kernels.select import right_view_row
from stereo_classic.matching._kernels.tags import disparity_tag, tag_disparities

_U = np.uint64


@njit(cache=False)
def _loops(PV, rv, wv, PH, rh, wh, PR, rr, wr, crow, cb, mv, qv, p1v, mh, qh, p1, srow, srow_r, tag):
    """The kernel's loops before pathvec: top path alone, top + left with their sum, right path into its sums."""
    D = tag_disparities(tag)
    top = np.int16(-1)
    nt = top
    for k in range(D):  # the top path alone, written to slot wv + 2E (a third slot: the warm-up rows' update)
        vv = _lr(PV, rv, crow[_U(cb + k)], mv, qv, p1v, k)
        PV[_U(wv + 2 * len(PV) // 4 + 1 + k)] = vv
        nt = umin16(nt, vv)
    nv = top
    nh = top
    for k in range(D):
        c = crow[_U(cb + k)]
        vv = _lr(PV, rv, c, mv, qv, p1v, k)
        vh = _lr(PH, rh, c, mh, qh, p1, k)
        PV[_U(wv + 1 + k)] = vv
        PH[_U(wh + 1 + k)] = vh
        nv = umin16(nv, vv)
        nh = umin16(nh, vh)
        srow[_U(cb + k)] = add16(vv, vh)
    nr = top
    ns = top
    for k in range(D):
        vr = _lr(PR, rr, crow[_U(cb + k)], mh, qh, p1, k)
        PR[_U(wr + 1 + k)] = vr
        nr = umin16(nr, vr)
        sm = add16(vr, srow_r[_U(cb + k)])
        srow_r[_U(cb + k)] = sm
        ns = umin16(ns, sm)
    return nt, nv, nh, nr, ns


@njit(cache=False)
def _vectors(PV, rv, wv, PH, rh, wh, PR, rr, wr, crow, cb, mv, qv, p1v, mh, qh, p1, srow, srow_r, tag):
    nt = top_path(PV, rv, wv + 2 * len(PV) // 4, crow, cb, mv, qv, p1v, tag)
    nv, nh, H = top_and_left(PV, rv, wv, load_vector(PH, rh + 1, tag), crow, cb, mv, qv, p1v, mh, qh, p1, srow, tag)
    store_vector(PH, wh + 1, H)  # the horizontal paths' vectors are the kernel's registers: stored to compare them
    nr, ns, R = right_path_sum(load_vector(PR, rr + 1, tag), crow, cb, mh, qh, p1, srow_r, tag)
    store_vector(PR, wr + 1, R)
    return nt, nv, nh, nr, ns


def test_vector_paths_only_for_one_two_or_four_registers():
    """The kernel takes the vector branch for D = 32, 64 or 128 (one, two or four 512-bit registers of int16), else
    the loops (three or five registers ran slower than the loops: ``vector_paths``)."""
    assert [D for D in (16, 32, 48, 64, 80, 96, 112, 128, 160, 192, 256, 4096) if vector_paths(disparity_tag(D))] == [
        32, 64, 128]


@pytest.fixture(params=[True, False], ids=["vpermi2w", "llvm-shuffles"])
def compiled(request, monkeypatch):
    """``_vectors`` and ``_right_sweep`` compiled afresh with each lowering of the lane moves (``pathvec._shifted``):
    the written-out ``vpermi2w`` (where 512-bit vectors are in use) and LLVM's own shuffles (elsewhere)."""
    if request.param and not pathvec._asm_permutes():
        pytest.skip(f"512-bit vectors not in use ({vectors.STATE}): the kernels compile with LLVM's shuffles (the "
                    "other parameter)")
    monkeypatch.setattr(pathvec, "ASM_PERMUTES", request.param)
    return SimpleNamespace(asm=request.param, vectors=njit(cache=False)(_vectors.py_func),
                           right_sweep=njit(cache=False)(_right_sweep.py_func))


def _lowered_as_asked(fn, asm):
    """The compiled function moves its lanes with the written-out ``vpermi2w`` exactly when asked to (so that each
    parameter checks its own lowering; LLVM's shuffles may be ``vpermi2w`` too, but not inline assembly)."""
    text = "".join(fn.inspect_llvm(sig) for sig in fn.signatures)
    assert ('asm "vpermi2w' in text) == asm


@pytest.mark.parametrize("D", [32, 64, 96, 128, 160])
def test_whole_vector_updates_equal_the_loops(D, compiled):
    """Every stored value and every minimum is the loops', bit for bit, at the kernels' value ranges: path values up to
    a few thousand (int16 sums of three of them stay far from the wrap), the sentinel either end of each slot, costs
    that make neighbours win and lose, penalties from the smallest to the largest the kernels give."""
    rng = np.random.default_rng(D)
    E = slot_size(D)
    tag = disparity_tag(D)
    W = 3
    for trial in range(40):
        hi = [8, 60, 400, 3000][trial % 4]
        PV = path_slots(4, D)
        PH = path_slots(2, D)
        PR = path_slots(2, D)
        for P, n in ((PV, 4), (PH, 2), (PR, 2)):
            for s in range(n):
                P[s * E + 1:s * E + 1 + D] = rng.integers(0, hi, D)
        crow = rng.integers(0, min(hi, 200), W * D).astype(np.int16)
        srow_r = rng.integers(0, 2 * hi, W * D).astype(np.int16)
        x = int(rng.integers(0, W))
        p1 = np.int16(rng.integers(1, 120))
        p1v = np.int16(rng.integers(1, 120))
        mv = np.int16(PV[E + 1:E + 1 + D].min())
        mh = np.int16(PH[E + 1:E + 1 + D].min())
        qv = np.int16(mv + rng.integers(p1v + 1, 1400))
        qh = np.int16(mh + rng.integers(p1 + 1, 1400))
        bufs = [(PV.copy(), PH.copy(), PR.copy(), np.zeros(W * D, np.int16), srow_r.copy()) for _ in range(2)]
        got = []
        for fn, (pv, ph, pr, sr, srr) in zip((_loops, compiled.vectors), bufs):
            got.append(fn(pv, E, 0, ph, E, 0, pr, E, 0, crow, x * D, mv, qv, p1v, mh, qh, p1, sr, srr, tag))
        assert got[0] == got[1], (D, trial)
        for want, have in zip(bufs[0], bufs[1]):
            np.testing.assert_array_equal(have, want)
        # the sentinels either end of every slot are never written
        for P in bufs[1][:3]:
            slots = P.reshape(-1, E)
            assert np.all(slots[:, 0] == _SENTINEL) and np.all(slots[:, D + 1] == _SENTINEL)
    _lowered_as_asked(compiled.vectors, compiled.asm and D in (32, 64, 128))


@njit(cache=False)
def _right_sweep(PR, crow, srow, rv, rd, p1, p2, fused, tag):
    """A row's right path from right to left, as the kernel runs it (the path vector in registers): with the right
    view in its window (``fused``: right pixel i - 1 finished at column step i, the last D at the end) or with
    ``right_path_sum`` alone. The last path vector is stored to ``PR[1:]``."""
    D = tag_disparities(tag)
    W = len(srow) // D
    R = vector_of(np.int16(0), tag)
    VV = vector_of(np.int16(32767), tag)
    VK = vector_of(np.int16(-1), tag)
    m = np.int16(0)
    minima = np.empty((W, 2), np.int16)
    for i in range(W):
        x = W - 1 - i
        if fused:
            nh, ns, fv, fk, R, VV, VK = right_path_view(R, crow, x * D, m, add16(m, p2), p1, srow, VV, VK, tag)
            if i > 0:
                rv[i - 1] = fv
                rd[i - 1] = fk
        else:
            nh, ns, R = right_path_sum(R, crow, x * D, m, add16(m, p2), p1, srow, tag)
        minima[x, 0] = nh
        minima[x, 1] = ns
        m = nh
    store_vector(PR, 1, R)
    if fused:
        store_vector(rv, W - 1, VV)
        store_vector(rd, W - 1, VK)
    return minima


@pytest.mark.parametrize("D", [32, 64, 128])
def test_right_view_in_the_sweep_equals_its_own_pass(D, compiled):
    """``right_path_view`` gives the sums, minima and path vectors of ``right_path_sum`` and the right view of
    ``select.right_view_row`` over the finished sums, bit for bit: few distinct values (many ties, where the lowest
    index must win), sums at INT16_MAX (which never claim a right pixel), rows narrower and wider than D."""
    rng = np.random.default_rng(7 * D)
    tag = disparity_tag(D)
    for trial in range(24):
        W = [1, 5, D - 1, D + 3, 3 * D + 7][trial % 5]
        hi = [3, 40, 2000][trial % 3]
        crow = rng.integers(0, min(hi, 100), W * D).astype(np.int16)
        srow = rng.integers(0, hi, W * D).astype(np.int16)
        if trial % 4 == 3:  # sums that stay at INT16_MAX whatever the path adds: a path of zeros, no cost
            crow[:] = 0
            srow[rng.random(W * D) < 0.5] = 32767
        got = []
        for fused in (False, True):
            PR = path_slots(2, D)
            sr = srow.copy()
            rv = np.full(W + D - 1, -5, np.int16)
            rd = np.full(W + D - 1, -5, np.int16)
            minima = compiled.right_sweep(PR, crow, sr, rv, rd, np.int16(9), np.int16(hi // 2 + 10), fused, tag)
            if not fused:
                right_view_row(sr, rv, rd, W, tag)
            got.append((PR, sr, minima, rv, rd))
        for want, have in zip(*got):
            np.testing.assert_array_equal(have, want, err_msg=f"D={D} trial={trial}")
    _lowered_as_asked(compiled.right_sweep, compiled.asm)


def test_wrong_buffers_are_refused_when_compiled():
    """A buffer of another dtype, a non-int16 penalty or a path vector of another range fails at compile time, naming
    what it got (not deep in LLVM)."""
    from numba.core.errors import TypingError

    @njit(cache=False)
    def call(P, crow, p1, tag):
        return top_path(P, 0, 0, crow, 0, np.int16(0), np.int16(9), p1, tag)

    tag = disparity_tag(32)
    with pytest.raises((TypeError, TypingError), match="contiguous 1-d int16 array, got array\\(float32"):
        call(np.zeros(64, np.float32), np.zeros(32, np.int16), np.int16(1), tag)
    with pytest.raises((TypeError, TypingError), match="must be int16, got int64"):
        call(path_slots(1, 32), np.zeros(32, np.int16), 1, tag)

    @njit(cache=False)
    def right(crow, srow, tag, other):  # a previous vector of another range than the tag's
        return right_path_sum(vector_of(np.int16(0), other), crow, 0, np.int16(0), np.int16(9), np.int16(1), srow, tag)

    with pytest.raises((TypeError, TypingError), match="path vector of 32 lanes expected, got PathVector\\(64\\)"):
        right(np.zeros(64, np.int16), np.zeros(64, np.int16), tag, disparity_tag(64))
