"""The arrays a call hands out, made from earlier ones only when nothing holds them (``_kernels.handout``)."""

from __future__ import annotations

import weakref

import numpy as np
import pytest

from stereo_classic.matching import StereoMatcher, compute_disparity
from stereo_classic.matching._kernels.handout import HANDOUT_SLOTS, HandOut, handout_allocator


def _pointer(arr: np.ndarray) -> int:
    return arr.__array_interface__["data"][0]


def test_a_dropped_array_is_handed_out_again_and_writable():
    h = HandOut()
    a = h("m", (4, 5), np.float32)
    a[:] = 1.0
    a.flags.writeable = False  # a holder may freeze it; once dropped it is ours again
    address = _pointer(a)
    del a
    b = h("m", (4, 5), np.float32)
    assert _pointer(b) == address and b.flags.writeable and b.flags.c_contiguous


@pytest.mark.parametrize("hold", ["array", "view", "view of a view", "weak reference", "memoryview"])
def test_an_array_something_holds_is_never_handed_out(hold):
    h = HandOut()
    a = h("m", (6, 7), np.float32)
    a[:] = 3.0
    holder = {"array": lambda: a, "view": lambda: a[1:, 2:], "view of a view": lambda: a[1:][:, ::2].T,
              "weak reference": lambda: weakref.ref(a), "memoryview": lambda: memoryview(a)}[hold]()
    address = _pointer(a)
    if hold != "array":
        del a
    for _ in range(2 * HANDOUT_SLOTS):
        b = h("m", (6, 7), np.float32)
        assert _pointer(b) != address
        b[:] = -1.0
    held = holder() if hold == "weak reference" else holder
    assert held is not None and np.all(np.asarray(held) == 3.0)


def test_another_name_never_gets_an_array_of_this_one():
    h = HandOut()
    address = _pointer(h("m", (4, 5), np.float32))  # dropped at once: free, and still kept here
    assert _pointer(h("n", (4, 5), np.float32)) != address
    assert _pointer(h("m", (4, 5), np.float32)) == address


@pytest.mark.parametrize("shape, dtype", [((4, 4), np.float64), ((8, 8), np.int64), ((8, 8), np.float32)])
def test_another_size_or_dtype_lets_the_free_arrays_of_the_old_one_go(shape, dtype):
    h = HandOut()
    a, b = h("m", (8, 8), np.float64), h("m", (8, 8), np.float64)
    del a, b
    assert h.free_bytes() == 2 * 8 * 8 * 8
    c = h("m", shape, dtype)  # the image size changed: the old ones are not kept beside the new one
    assert c.shape == shape and c.dtype == dtype and h.free_bytes() == 0
    held = h("m", shape, dtype)
    assert not np.shares_memory(held, c)
    del c
    assert h.free_bytes() == held.nbytes


def test_it_keeps_the_last_slots_and_says_what_it_keeps_free():
    h = HandOut()
    held = [h("m", (8, 8), np.float64) for _ in range(HANDOUT_SLOTS + 2)]
    assert h.free_bytes() == 0
    del held[:2]  # the two oldest are no longer kept here: freed
    assert h.free_bytes() == 0
    held.clear()
    assert h.free_bytes() == HANDOUT_SLOTS * 8 * 8 * 8


def test_without_a_workspace_every_array_is_new():
    new = handout_allocator(None)
    a = new("m", (3, 3), np.uint8)
    b = new("m", (3, 3), np.uint8)
    assert a is not b and not np.shares_memory(a, b) and a.shape == (3, 3) and a.dtype == np.uint8


def _pair(seed, shift):
    right = np.random.default_rng(seed).integers(0, 256, (48, 96), dtype=np.uint8)
    return np.roll(right, shift, axis=1), right


def _maps(res):
    return [a for a in (res.disparity, res.filled_disparity, res.filled, res.disparity_right, res.left_gray)
            if a is not None]


def test_matcher_writes_a_dropped_results_maps_again_and_never_a_held_ones():
    m = StereoMatcher(num_disparities=16, speckle_size=20)
    pairs = [_pair(1, 5), _pair(2, 9), _pair(3, 3)]
    first = m.compute(*pairs[0])
    addresses = {_pointer(a) for a in _maps(first)}
    assert len(addresses) == 5  # filled and measured maps, mask, right view, grey image: five arrays
    view = first.disparity[4:, 8:]
    kept_view = view.copy()
    second = m.compute(*pairs[1])
    kept_second = [a.copy() for a in _maps(second)]
    del first  # only a view of its measured map is held
    third = m.compute(*pairs[2])
    reused = {_pointer(a) for a in _maps(third)} & addresses
    assert reused and _pointer(third.disparity) not in reused  # the others come back, the viewed one does not
    np.testing.assert_array_equal(view, kept_view)
    for a, b in zip(_maps(second), kept_second):
        np.testing.assert_array_equal(a, b)
    for res, pair in ((second, pairs[1]), (third, pairs[2])):
        fresh = compute_disparity(*pair, m.params)
        for a, b in zip(_maps(res), _maps(fresh)):
            np.testing.assert_array_equal(a, b)
        assert res.validity == fresh.validity
    m.release()
    assert m.compute(*pairs[0]).disparity.shape == (48, 96)
