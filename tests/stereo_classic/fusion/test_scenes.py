"""The planted test scene is itself a consistent stereo pair (the fusion tests rely on it)."""

from __future__ import annotations

import numpy as np

from tests.helpers.scenes import make_rig, planted_scene


def test_planted_scene_is_a_consistent_stereo_pair():
    """Every left pixel reappears in the right image shifted by its ground-truth disparity."""
    rig = make_rig(200, 120, focal_px=600.0, baseline_m=0.1)  # f B = 60: 3 m -> 20 px, 6 m -> 10 px
    left, right, gt, _ = planted_scene(width=200, height=120, z_box=3.0, z_wall=6.0, box=(60, 30, 140, 90), rig=rig)
    assert set(np.unique(gt)) == {10.0, 20.0}
    assert gt[60, 100] == 20.0 and gt[10, 10] == 10.0
    ys, xs = np.mgrid[0:120, 0:200]
    xr = xs - gt.astype(int)
    # Visible in both views: inside the right image and not hidden behind the box there.
    ok = xr >= 0
    hidden = (gt == 10.0) & (ys >= 30) & (ys < 90) & (xr + 20 >= 60) & (xr + 20 < 140)
    ok &= ~hidden
    diff = np.abs(left[..., 0].astype(int)[ok] - right[..., 0].astype(int)[ys[ok], xr[ok]])
    assert diff.max() <= 1
