"""Obstacles from ground-frame points: clustering, corridor, heights, free distances, clock hours."""

from __future__ import annotations

import numpy as np
import pytest

from stereo_classic.guide import GuideParams, clock_of, find_obstacles, free_distances


def _face(lat0, lat1, fwd, h0, h1, step=0.02):
    """Points of a vertical face across the walking direction, each standing for step**2 square metres."""
    lat, hgt = np.meshgrid(np.arange(lat0, lat1, step), np.arange(h0, h1, step))
    pts = np.column_stack([lat.ravel(), np.full(lat.size, fwd), hgt.ravel()])
    return pts, np.full(len(pts), step * step)


@pytest.mark.parametrize("bearing, hour", [(0, 12), (14.9, 12), (15.1, 1), (-29, 11), (-80, 9), (89, 3), (180, 6)])
def test_clock_of(bearing, hour):
    assert clock_of(bearing) == hour


def test_box_in_the_corridor():
    pts, area = _face(-0.3, 0.3, 2.5, 0.0, 0.8)
    obs, grid = find_obstacles(pts, area, GuideParams())
    assert len(obs) == 1
    o = obs[0]
    assert o.nearest_m == pytest.approx(2.5, rel=0.02) and o.clock == 12
    assert o.top_m == pytest.approx(0.8, abs=0.05) and o.bottom_m == pytest.approx(0.1, abs=0.05)
    assert o.width_m == pytest.approx(0.6, abs=0.15)
    assert grid.occupied.dtype == bool and grid.occupied.shape == (50, 100) and grid.mask.shape == (len(pts),)


def test_head_height_bar_counts_and_higher_things_do_not():
    bar, a1 = _face(-0.5, 0.5, 3.0, 1.7, 1.8)
    sign, a2 = _face(-0.5, 0.5, 2.0, 2.2, 2.5)             # above head height
    obs, _ = find_obstacles(np.vstack([bar, sign]), np.concatenate([a1, a2]), GuideParams())
    assert len(obs) == 1 and obs[0].nearest_m == pytest.approx(3.0, rel=0.02) and obs[0].bottom_m > 1.6


def test_outside_the_corridor_and_ground_points_are_not_obstacles():
    wall, a1 = _face(1.0, 1.5, 2.0, 0.0, 2.0)               # right of a 1 m corridor
    floor = np.column_stack([np.zeros(500), np.linspace(1, 4, 500), np.full(500, 0.05)])
    obs, grid = find_obstacles(np.vstack([wall, floor]), np.concatenate([a1, np.full(500, 0.01)]), GuideParams())
    assert obs == [] and grid.occupied.any()
    assert find_obstacles(wall, a1, GuideParams(corridor_width=3.0))[0][0].clock == 1


def test_free_distances():
    pts = np.array([[0.0, 2.0], [-1.5, 1.5]])
    free = free_distances(pts, np.array([0.0, -45.0, 45.0]), 1.0, 5.0)
    assert free[0] == pytest.approx(2.0) and free[1] == pytest.approx(np.hypot(1.5, 1.5)) and free[2] == 5.0
    assert free.dtype == np.float64 and free_distances(np.zeros((0, 2)), np.array([0.0]), 1.0, 4.0)[0] == 4.0


def test_front_and_top_of_a_box_are_one_obstacle():
    front, a1 = _face(-0.3, 0.3, 2.0, 0.0, 0.8)
    lat, fwd = np.meshgrid(np.arange(-0.3, 0.3, 0.02), np.arange(2.25, 2.4, 0.02))   # the top, past a 1-cell gap
    top = np.column_stack([lat.ravel(), fwd.ravel(), np.full(lat.size, 0.8)])
    obs, _ = find_obstacles(np.vstack([front, top]), np.concatenate([a1, np.full(len(top), 4e-4)]), GuideParams())
    assert len(obs) == 1 and obs[0].depth_m > 0.3
