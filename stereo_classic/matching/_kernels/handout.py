"""The arrays a call hands out (a result's maps), made from those it handed out before that nothing holds any more.

A fresh array of a few MB is mapped by the C library for the call and faulted in page by page as it is first
written, on the workers, who then wait on each other in the kernel (the OAK-D VGA pair: about 940 page faults a
call; KITTI 1450). An array handed out earlier whose only reference is the one kept here (no result, no view of it,
no weak reference: nothing outside can reach it) is written again instead. The caller gets either a new array or
one nobody else can see, so what it holds never changes under it.
"""

from __future__ import annotations

import sys
import weakref
from typing import Any, Callable

import numpy as np

__all__ = ["HANDOUT_SLOTS", "HandOut", "handout_allocator"]

#: Arrays kept per name: the last ones handed out. A pipeline holds a frame's result while the next frames are
#: matched (``run`` writes frame N - 1 while it matches frame N + 1), so the one handed out before last is usually
#: still held; the third is free again.
HANDOUT_SLOTS = 3


def _refs(arr: np.ndarray) -> int:
    """``arr``'s reference count as read here: the holders' and those this call adds (callers pass a list's item)."""
    return sys.getrefcount(arr)


def _free_refs() -> int:
    """The count ``_refs`` reads for an array only a list holds, measured the way ``HandOut`` reads it: what a
    call adds is the interpreter's business (3.14 borrows some references another version counts), so it is not
    assumed."""
    kept = [np.empty(0)]
    return _refs(kept[0])


#: ``_refs`` of an array that nothing but the kept list holds.
_FREE = _free_refs()


def _unheld(kept: list[np.ndarray], i: int) -> bool:
    return _refs(kept[i]) == _FREE and weakref.getweakrefcount(kept[i]) == 0


class HandOut:
    """``handout(name, shape, dtype)``: an uninitialised C-contiguous array of that shape and dtype, one kept under
    ``name`` that nothing else holds, else a new one (kept: the last ``HANDOUT_SLOTS`` per name). Not thread-safe
    (one per workspace, used under its caller's lock)."""

    def __init__(self) -> None:
        self._kept: dict[str, list[np.ndarray]] = {}

    def __call__(self, name: str, shape: tuple[int, ...], dtype) -> np.ndarray:
        shape, dtype = tuple(int(n) for n in shape), np.dtype(dtype)
        kept = self._kept.setdefault(name, [])
        for i in range(len(kept)):
            if kept[i].shape == shape and kept[i].dtype == dtype and _unheld(kept, i):
                arr = kept.pop(i)
                arr.flags.writeable = True  # its own memory (made below): allowed whatever a holder set
                kept.append(arr)  # the most recently handed out last
                return arr
        # free ones of another shape or dtype (the image size changed) are let go rather than kept beside the new one
        kept[:] = [kept[i] for i in range(len(kept)) if not _unheld(kept, i)]
        arr = np.empty(shape, dtype)  # owns its memory: a view of it references it (``_refs`` counts those)
        kept.append(arr)
        if len(kept) > HANDOUT_SLOTS:
            del kept[0]  # the oldest: whoever holds it keeps it
        return arr

    def free_bytes(self) -> int:
        """Bytes kept that nothing else holds (what this keeps alive beyond the results)."""
        return sum(kept[i].nbytes for kept in self._kept.values() for i in range(len(kept)) if _unheld(kept, i))


def handout_allocator(workspace) -> Callable[[str, tuple[int, ...], Any], np.ndarray]:
    """``workspace.handout`` (a ``core.Workspace``'s), or a new ``np.empty`` array every time without a workspace."""
    if workspace is not None:
        return workspace.handout
    return lambda name, shape, dtype: np.empty(shape, dtype)
