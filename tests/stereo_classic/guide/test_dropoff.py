"""Drop-offs from ground-frame points: a step down at a known distance, none on flat ground or a small step."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_classic.guide import GuideParams, find_dropoff


def _ground(edge, drop, lateral_shift=0.0, h=1.2):
    """A floor up to ``edge`` metres, then ``drop`` m lower; the lower floor hides behind the edge (seen from h)."""
    lat, fwd = np.meshgrid(np.arange(-3.0, 3.0, 0.05), np.arange(0.8, 8.0, 0.05))
    lat, fwd = lat.ravel() + lateral_shift, fwd.ravel()
    hidden = (fwd > edge) & (fwd < edge * (h + drop) / h)
    hgt = np.where(fwd < edge, 0.0, -drop)
    keep = ~hidden
    pts = np.column_stack([lat[keep], fwd[keep], hgt[keep]])
    area = (fwd[keep] * 4 / 300.0) ** 2
    return pts, area


@pytest.mark.parametrize("edge, drop", [(2.0, 0.2), (3.0, 0.4), (4.0, 1.0)])
def test_step_down_distance(edge, drop):
    pts, area = _ground(edge, drop)
    d = find_dropoff(pts, area, GuideParams(), camera_height=1.2)
    assert d is not None
    assert d.distance_m == pytest.approx(edge, rel=0.15) and d.drop_m == pytest.approx(drop, abs=0.05)
    assert d.clock == 12


def test_flat_ground_small_steps_and_far_edges_are_not_drop_offs():
    flat, area = _ground(50.0, 0.0)
    assert find_dropoff(flat, area, GuideParams(), camera_height=1.2) is None
    kerb, area = _ground(2.0, 0.1)                          # lower than step_height = 0.15
    assert find_dropoff(kerb, area, GuideParams(), camera_height=1.2) is None
    far, area = _ground(6.0, 0.5)                           # beyond look_ahead = 5 m
    assert find_dropoff(far, area, GuideParams(), camera_height=1.2) is None


def test_bearing_turns_the_strip():
    pts, area = _ground(3.0, 0.4)
    d = find_dropoff(pts, area, GuideParams(), camera_height=1.2, bearing_deg=20.0)
    assert d is not None and d.distance_m == pytest.approx(3.0 / np.cos(np.radians(20.0)), rel=0.15)
