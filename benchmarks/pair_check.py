"""The pair check's shares on every shared scene, as given and swapped, and on pairs that are not pairs.

    python -m benchmarks.pair_check [--data ../shared/data]

Per scene at the range ``run`` picks (its ground truth's maximum rounded up to 16, else 128): the fractions of
the half-size look's pixels consistent at disparities only the given order can have and only the exchanged
order can have (``FrameChecker.order_shares``), for the pair as given and swapped, and the check's warning. Then
two OAK-D left images with another scene's right image (unrelated) and every OAK-D pair with the right image
shifted by 15 rows (not rectified). "match": the share of the frame's own match (default matcher) consistent at
disparities only the given order can have, which the pair check reads first (``PAIR_CLEAR``). The numbers quoted
in ``stereo_classic.checks`` come from here.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]


def _range(scene) -> int:
    return int(16 * math.ceil((scene.max_disparity + 1) / 16)) if scene.max_disparity else 128


def _shares(left, right, num: int) -> tuple[float, float, str, float]:
    """(given, other, the look's warning, match): the look's shares and its answer, and the share of the frame's
    own match (default matcher) that the pair check reads first (``FrameChecker.given_share``)."""
    from stereo_classic.checks import FrameChecker
    from stereo_classic.matching import DisparityMap, SGMParams, StereoMatcher

    checker = FrameChecker(SGMParams(num_disparities=num))
    matcher = StereoMatcher(checker.params)
    try:
        look = checker._look(checker.halves(left, right))
        given, other = checker.order_shares(look) if look is not None else (math.nan, math.nan)
        blank = DisparityMap(np.zeros(left.shape[:2], np.float32), None, SGMParams())
        warning = checker.check_pair(left, right, blank)
        match = checker.given_share(matcher.compute(left, right))
    finally:
        checker.close()
        matcher.release()
    return given, other, "-" if warning is None else warning.code, math.nan if match is None else match


def main(argv=None) -> int:
    from stereo_classic.datasets import iter_scenes

    ap = argparse.ArgumentParser(prog="python -m benchmarks.pair_check", description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=REPO.parent / "shared" / "data")
    a = ap.parse_args(argv)
    scenes = list(iter_scenes(a.data))
    print(f"{'scene':28s} {'range':>5s}  as given: given other warning match  |  swapped: given other warning "
          "match")
    for s in scenes:
        n = _range(s)
        g = _shares(s.left, s.right, n)
        w = _shares(s.right, s.left, n)
        print(f"{s.name[-28:]:28s} {n:5d}  {g[0]:14.2f} {g[1]:5.2f} {g[2]:>13s} {g[3]:5.2f}  |  {w[0]:13.2f} "
              f"{w[1]:5.2f} {w[2]:>13s} {w[3]:5.2f}")
    oakd = [s for s in scenes if s.left.shape[:2] == (480, 640)]
    for a_, b_ in zip(oakd[::2], oakd[1::2]):
        g = _shares(a_.left, b_.right, 64)
        print(f"unrelated {a_.name} + {b_.name}: given {g[0]:.2f} other {g[1]:.2f} {g[2]} match {g[3]:.2f}")
    for s in oakd:
        g = _shares(s.left, np.roll(s.right, 15, axis=0), 64)
        print(f"{s.name} right image 15 rows down: given {g[0]:.2f} other {g[1]:.2f} {g[2]} match {g[3]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
