"""The Kalman update in q's dimension equals the 3 × 3 one (stslam/kalman/isotropic.py)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.kalman.ekf import update
from stslam.kalman.isotropic import isotropic_update
from stslam.sim.marker_camera import MarkerCamera
from stslam.selection.selector import select_track
from stslam.selection.settings import make_settings
from stslam.sim.track_generator import generate_tracks


@pytest.mark.parametrize("dof, order", [(1, 1), (1, 2), (2, 1), (3, 0)])
def test_isotropic_update_equals_the_full_update(dof, order):
    rng = np.random.default_rng(dof * 10 + order)
    n = dof * (order + 1)
    L = rng.normal(size=(n, n))
    P, x, y, J = L @ L.T + 0.1 * np.eye(n), rng.normal(size=n), rng.normal(size=3), rng.normal(size=(3, dof))
    H = np.zeros((3, n))
    H[:, :dof] = J
    full, fast = update(x, P, y, H, 0.04 * np.eye(3)), isotropic_update(x, P, y, J, 0.04)
    for a, b in [(full.x, fast.x), (full.P, fast.P), (full.S, fast.S)]:
        assert np.allclose(a, b, rtol=1e-10, atol=1e-12)
    assert fast.nis == pytest.approx(full.nis, rel=1e-10)
    assert fast.log_likelihood == pytest.approx(full.log_likelihood, rel=1e-10)


def test_selection_with_the_fast_update_decides_as_with_the_full_one():
    sigma = {"static": 0.01, "prismatic": 3.0, "revolute": 3.0}
    common = dict(measurement_sigma_m=0.002, smoothing_sigma=3.0, dt=1 / 30, selector="imm", tau=0.9,
                  hold_steps=15, min_motion_m=0.1, scale_cap_m=1.0, fit_spacing_m=0.005)
    for track in generate_tracks(4, 70, camera=MarkerCamera()):
        a = select_track(track.points_world, make_settings(sigma, **common))
        b = select_track(track.points_world, make_settings(sigma, fast_update=True, **common))
        assert (a.chosen, a.chosen_step) == (b.chosen, b.chosen_step)
        # Round-off grows a little through the chain (at most 1e-4 on these tracks).
        assert np.allclose(a.mu_history, b.mu_history, atol=1e-3, equal_nan=True)
