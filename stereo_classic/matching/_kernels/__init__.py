"""The numba kernels of the matcher (private: use ``stereo_classic.matching``).

* ``core``: the fused two-thread SGM passes and their driver (``sgm_match``, ``Workspace``).
* ``cost``: census and SAD matching costs.
* ``intrinsics``: int16 arithmetic and popcount as LLVM operations.

Importing them compiles nothing: numba compiles (or loads from its cache) on the first call.
The kernels import nothing from the rest of the project.
"""

from __future__ import annotations

__all__: list[str] = []
