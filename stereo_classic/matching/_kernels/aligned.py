"""Arrays whose vectors start on a cache line: the kernels' row buffers and the cost images.

numpy's allocator gives 16-byte aligned memory, so a 64-byte vector (32 int16 lanes of AVX-512, two 256-bit
vectors) read or written at a pixel's first disparity spans two cache lines and costs a split access. The
kernels read and write every pixel's disparities from such buffers in whole vectors, so where the buffers start
matters: with the path slots padded too (``rowpass.slot_size``), the KITTI pair at 128 disparities took 60.4 -> 55.0 ms
at 1 thread and 33.8 -> 32.0 at 2 threads, the OAK-D VGA pair 17.3 -> 15.4 ms at 2 threads, bit-identical output
(docs/matching.md, "Fourth round: buffers on a cache line").
"""

from __future__ import annotations

import numpy as np

__all__ = ["ALIGNMENT", "ALIGN_SLACK", "aligned_empty", "aligned_zeros"]

#: Bytes of a cache line (and of the widest vector): where each buffer's vectors start.
ALIGNMENT = 64
#: The bytes an aligned array may take beyond its own (the memory estimates count them per array).
ALIGN_SLACK = ALIGNMENT


def aligned_empty(shape: int | tuple[int, ...], dtype, lead: int = 0) -> np.ndarray:
    """An uninitialised C-contiguous array whose element ``lead`` (in flat order) starts on an ``ALIGNMENT``-byte
    boundary (``lead=1``: a buffer whose element 0 is a sentinel before the aligned data).

    >>> a = aligned_empty((3, 5), np.int16, lead=1)
    >>> a.shape, a.ctypes.data % ALIGNMENT
    ((3, 5), 62)
    """
    dtype = np.dtype(dtype)
    shape = (int(shape),) if np.isscalar(shape) else tuple(int(n) for n in shape)
    nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    lead_bytes = int(lead) * dtype.itemsize
    if ALIGNMENT % dtype.itemsize:
        raise ValueError(f"`dtype` must have an item size that divides {ALIGNMENT} bytes, got {dtype}")
    if not 0 <= lead_bytes < ALIGNMENT:
        raise ValueError(f"`lead` must be a count of {dtype} elements within {ALIGNMENT} bytes, got {lead}")
    raw = np.empty(nbytes + ALIGNMENT, np.uint8)
    start = (-(raw.ctypes.data + lead_bytes)) % ALIGNMENT  # raw[start + lead_bytes] is aligned
    return raw[start:start + nbytes].view(dtype).reshape(shape)


def aligned_zeros(shape: int | tuple[int, ...], dtype, lead: int = 0) -> np.ndarray:
    """``aligned_empty`` filled with zeros."""
    out = aligned_empty(shape, dtype, lead)
    out[...] = 0
    return out
