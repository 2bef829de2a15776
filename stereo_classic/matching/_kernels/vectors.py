"""512-bit vectors for the kernels' int16 loops on CPUs where they cost no clock speed.

LLVM tunes the Intel cores with AVX-512 (Skylake-SP and every later server and client core) to prefer 256-bit
vectors, because 512-bit instructions lowered the clock of the first of them. The kernels' inner loops run over
the disparities of a pixel in int16 (64-256 contiguous lanes, in L1 / L2 since the row-buffer design) and are
bound by arithmetic, so the preference halves their lanes (16 instead of 32). Measured on an Emerald Rapids core
(KITTI pair, the default matcher, 3 x 12 calls alternated with the 256-bit build in separate processes,
``timings_ms["aggregate"]`` min / median): 1 thread 79.7 / 93.6 -> 69.4 / 85.6 ms, 2 threads 40.4 / 52.0 -> 37.5 /
47.1; the 8-path kernel (bound by its sum volume's memory traffic) unchanged; the output bit-identical (integer
arithmetic; no fast-math anywhere: float results do not depend on the vector width).

numba has one target machine per process, made when it first compiles or loads a function: :func:`prefer_wide_vectors`
(run when the kernels are imported) sets numba's CPU features (``numba.config.CPU_FEATURES``, what
``NUMBA_CPU_FEATURES`` sets) to the host's own with ``-prefer-256-bit`` added, before that. It changes nothing
(and says why in :data:`STATE`) when ``$STEREO_CLASSIC_WIDE_VECTORS`` is ``0``, when the user set
``NUMBA_CPU_FEATURES`` or ``NUMBA_CPU_NAME``, when the CPU lacks AVX-512BW, when it is one whose 512-bit
instructions do lower the clock (Skylake-SP, Cascade Lake, Cooper Lake, Knights Landing / Mill), or when numba's
CPU target was made before (something compiled before ``stereo_classic`` was imported). Other numba code of the
process gets the same features: the same results, its vectors possibly wider.
"""

from __future__ import annotations

import os

__all__ = ["STATE", "prefer_wide_vectors"]

#: What :func:`prefer_wide_vectors` did: "wide" (512-bit vectors preferred) or the reason it left numba alone.
STATE: str = "not tried"

#: LLVM CPU names whose 512-bit instructions lower the core's clock (AVX-512 "licence" levels).
_CLOCK_DROP = frozenset({"skylake-avx512", "cascadelake", "cooperlake", "knl", "knm"})


def prefer_wide_vectors() -> str:
    """Prefer 512-bit vectors in numba's code on a CPU where they are free (see the module); returns :data:`STATE`."""
    global STATE
    if os.environ.get("STEREO_CLASSIC_WIDE_VECTORS", "").strip() == "0":
        STATE = "off: STEREO_CLASSIC_WIDE_VECTORS=0"
        return STATE
    if os.environ.get("NUMBA_CPU_FEATURES") is not None or os.environ.get("NUMBA_CPU_NAME") is not None:
        STATE = "off: NUMBA_CPU_FEATURES / NUMBA_CPU_NAME set by the user"
        return STATE
    try:
        import llvmlite.binding as ll
        from numba.core import config, registry

        if "_toplevel_target_context" in vars(registry.cpu_target):
            STATE = "off: numba's CPU target was made before stereo_classic was imported"
            return STATE
        if config.CPU_FEATURES is not None or config.CPU_NAME is not None:
            STATE = "off: numba.config.CPU_FEATURES / CPU_NAME set"
            return STATE
        ll.initialize_native_target()
        name = ll.get_host_cpu_name()
        features = ll.get_host_cpu_features()
        if not features.get("avx512bw", False):
            STATE = f"off: {name} has no AVX-512BW"
            return STATE
        if name in _CLOCK_DROP:
            STATE = f"off: {name} lowers its clock for 512-bit instructions"
            return STATE
        config.CPU_FEATURES = features.flatten() + ",-prefer-256-bit"
    except Exception as exc:  # noqa: BLE001 - an optimisation: never a reason for the import to fail
        STATE = f"off: {type(exc).__name__}: {exc}"
        return STATE
    STATE = "wide"
    return STATE
