"""The structure correction's covariance from a fit (stslam/articulation/correction.py, SPEC 6.3(b))."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.articulation.correction import corrected_position, fit_correction_covariance
from stslam.articulation.models import MODELS
from stslam.errors import DegenerateFitError


def _fit_correction(name, structure, points, iterations=6):
    """δ fitted by Gauss–Newton over (δ, q_1 … q_n) to ``points`` from δ = 0 (the estimator the bound is for)."""
    size = 6 if name == "revolute" else 4
    delta, q = np.zeros(size), MODELS[name].motion_variable(structure, points)[:, 0].copy()
    for _ in range(iterations):
        J, r = np.zeros((3 * len(points), size + len(points))), np.zeros(3 * len(points))
        for i, z in enumerate(points):
            m, dm_dq, dm_ddelta = corrected_position(name, structure, q[i], delta)
            r[3 * i:3 * i + 3], J[3 * i:3 * i + 3, :size], J[3 * i:3 * i + 3, size + i] = z - m, dm_ddelta, dm_dq
        step = np.linalg.lstsq(J, r, rcond=None)[0]
        delta, q = delta + step[:size], q + step[size:]
    return delta


def _points(name):
    if name == "prismatic":
        s = np.linspace(0.0, 0.4, 30)
        return np.column_stack([1.0 + 0.6 * s, 2.0 + 0.8 * s, 0.5 + 0.0 * s])
    phi = np.linspace(0.2, 2.2, 30)
    return np.column_stack([1.0 + 0.5 * np.cos(phi), 2.0 + 0.5 * np.sin(phi), np.full_like(phi, 0.7)])


@pytest.mark.parametrize("name", ["prismatic", "revolute"])
def test_the_pose_jacobian_is_the_fits_answer_to_a_rigid_pose_error(name):
    points = _points(name)
    structure = MODELS[name].fit(points)
    robot = np.array([-0.5, 0.3])
    _, A = fit_correction_covariance(name, structure, points, 0.04, robot)
    e = np.array([0.004, -0.006, 0.003])  # (dx, dy, dθ) of the pose the points were mapped through
    c, s = np.cos(e[2]), np.sin(e[2])
    moved = points.copy()
    moved[:, :2] = (points[:, :2] - robot) @ np.array([[c, s], [-s, c]]) + robot + e[:2]
    np.testing.assert_allclose(_fit_correction(name, structure, moved), A @ e, atol=2e-4)


def test_the_covariance_is_the_fits_spread_on_a_line():
    points = _points("prismatic")
    structure = MODELS["prismatic"].fit(points)
    cov, _ = fit_correction_covariance("prismatic", structure, points, 0.04, [0.0, 0.0])
    rng = np.random.default_rng(3)
    fits = np.array([_fit_correction("prismatic", structure, points + rng.normal(0.0, 0.04, points.shape))
                     for _ in range(150)])
    np.testing.assert_allclose(fits.std(axis=0), np.sqrt(np.diag(cov)), rtol=0.2)


def test_points_that_do_not_determine_the_correction_are_refused():
    points = np.tile([1.0, 2.0, 0.5], (5, 1))
    structure = MODELS["prismatic"].fit(_points("prismatic"))
    with pytest.raises(DegenerateFitError, match="do not determine the prismatic correction"):
        fit_correction_covariance("prismatic", structure, points, 0.04, [0.0, 0.0])
    with pytest.raises(ValueError, match="sigma_m: expected a finite number > 0"):
        fit_correction_covariance("prismatic", structure, _points("prismatic"), 0.0, [0.0, 0.0])
