"""The kernels' preference for 512-bit vectors (``stereo_classic.matching._kernels.vectors``): when it applies, when
it leaves numba alone, and that the disparity does not depend on it."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[3]

_PROBE = """
import json, sys
{before}
import stereo_classic
from numba.core import config
from stereo_classic.matching._kernels import vectors
print(json.dumps({{"state": vectors.STATE, "features": config.CPU_FEATURES}}))
"""


def _probe(env: dict[str, str], before: str = "") -> dict:
    full = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CPU_FEATURES", "NUMBA_CPU_NAME",
                                                               "STEREO_CLASSIC_WIDE_VECTORS")}
    full.update(env)
    full["PYTHONPATH"] = str(REPO) + os.pathsep + full.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, "-c", _PROBE.format(before=before)], env=full, capture_output=True,
                         text=True, timeout=300, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _host() -> tuple[str, dict]:
    import llvmlite.binding as ll

    ll.initialize_native_target()
    return ll.get_host_cpu_name(), dict(ll.get_host_cpu_features())


def test_wide_vectors_where_the_cpu_has_them_free():
    from stereo_classic.matching._kernels.vectors import _CLOCK_DROP

    name, features = _host()
    got = _probe({})
    if features.get("avx512bw") and name not in _CLOCK_DROP:
        assert got["state"] == "wide" and got["features"].endswith(",-prefer-256-bit")
        assert "+avx512bw" in got["features"]
    else:
        assert got["state"].startswith("off: ") and got["features"] is None


@pytest.mark.parametrize("env, before, reason", [
    ({"STEREO_CLASSIC_WIDE_VECTORS": "0"}, "", "off: STEREO_CLASSIC_WIDE_VECTORS=0"),
    ({"NUMBA_CPU_NAME": "generic"}, "", "off: NUMBA_CPU_FEATURES / NUMBA_CPU_NAME set by the user"),
    ({}, "import numba\nnumba.njit(lambda x: x + 1)(1)", "off: numba's CPU target was made before"),
])
def test_numba_is_left_alone_when_told_or_too_late(env, before, reason):
    got = _probe(env, before)
    assert got["state"].startswith(reason)
    if "NUMBA_CPU_NAME" not in env:
        assert got["features"] is None


_MATCH = """
import sys, numpy as np
import stereo_classic as sc
from stereo_classic.matching._kernels import vectors
rng = np.random.default_rng(3)
left = (rng.random((70, 150)) * 255).astype(np.uint8)
right = np.roll(left, -9, axis=1)
out = []
for kw in ({}, {"lr_mode": "opencv", "threads": 3}, {"paths": 8, "cost": "census"}):
    d = sc.compute_disparity(left, right, sc.SGMParams(num_disparities=32, **kw))
    out.append(d.disparity)
    if d.disparity_right is not None:
        out.append(d.disparity_right)
np.save(sys.argv[1], np.stack(out))
print(vectors.STATE)
"""


def test_the_disparity_does_not_depend_on_the_vector_width(tmp_path):
    """Integer arithmetic and no fast-math: 512-bit and 256-bit builds give the same maps, bit for bit."""
    maps, states = [], []
    for i, env in enumerate(({}, {"STEREO_CLASSIC_WIDE_VECTORS": "0"})):
        full = {k: v for k, v in os.environ.items() if k != "STEREO_CLASSIC_WIDE_VECTORS"}
        full.update(env)
        full["PYTHONPATH"] = str(REPO) + os.pathsep + full.get("PYTHONPATH", "")
        path = tmp_path / f"maps{i}.npy"
        out = subprocess.run([sys.executable, "-c", _MATCH, str(path)], env=full, capture_output=True, text=True,
                             timeout=600, check=True)
        states.append(out.stdout.strip().splitlines()[-1])
        maps.append(np.load(path))
    assert states[1].startswith("off: STEREO_CLASSIC_WIDE_VECTORS=0")
    assert np.isfinite(maps[0]).mean() > 0.5
    np.testing.assert_array_equal(maps[0], maps[1])
