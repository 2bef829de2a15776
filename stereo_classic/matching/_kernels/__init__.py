"""The numba kernels of the matcher (private: use ``stereo_classic.matching``).

* ``core``: the driver (``sgm_match``, ``Workspace``): stripes and buffers; ``workers``: the worker threads.
* ``rowpass``: the one-sweep kernel of the default 3 paths; ``aggregate``: the two-pass kernel of 4 and 8 paths.
* ``cost``: census, census + gradient and SAD costs, one row at a time (``colsums``: their window sums' columns);
  ``select``: the winner of a row.
* ``speckle``: the speckle filter's connected components in stripes.
* ``intrinsics``: int16 arithmetic and popcount as LLVM operations; ``pipeline``: the no-alias compiler pipeline.
* ``aligned``: arrays whose vectors start on a cache line (the row buffers, the cost images).
* ``vectors``: 512-bit vectors for the int16 loops where the CPU runs them at full clock (set here, on import,
  before numba compiles anything).

Importing them compiles nothing: numba compiles (or loads from its cache) on the first call.
The kernels import nothing from the rest of the project.
"""

from __future__ import annotations

from stereo_classic.matching._kernels.vectors import prefer_wide_vectors

prefer_wide_vectors()

__all__: list[str] = []
