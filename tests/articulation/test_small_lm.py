"""The compiled Levenberg–Marquardt of the circle fits (stslam.articulation.small_lm, SPEC 2.3, 18)."""

import numpy as np
import pytest
from scipy.optimize import least_squares

from stslam.articulation.small_lm import CIRCLE_2D, WEIGHTED_CIRCLE_3D, levenberg_marquardt, residuals_jacobian

NO_WEIGHTS, NO_BASIS = np.ones(0), np.zeros((3, 3))


def _door_window(rng, radius, opening, sigma=0.04):
    """A door's point about the z axis: at rest, swinging open, at rest (noisy)."""
    phi = np.concatenate([np.zeros(20), np.linspace(0.0, opening, 10), np.full(20, opening)])
    p = np.column_stack([radius * np.cos(phi), radius * np.sin(phi), np.full(phi.size, 1.0)])
    return p + rng.normal(0.0, sigma, p.shape)


def _random_3d(rng):
    """A door's window with random weights, started where revolute_log_odds starts: the unweighted fit."""
    from stslam.articulation.models import get_model
    points = _door_window(rng, radius=rng.uniform(0.2, 1.0), opening=rng.uniform(0.8, 2.0))
    root_w = np.sqrt(rng.uniform(0.5, 50.0, len(points)))
    start = get_model("revolute").fit(points)
    basis = np.stack([start.v1, start.v2, np.cross(start.v1, start.v2)])
    params = np.concatenate([start.centre_world, [0.0, 0.0, start.radius]])
    return points, root_w, basis, params


def _random_jacobian_3d(rng):
    """Random circle parameters (tilted) and a random basis: the Jacobian's test."""
    points = _door_window(rng, radius=rng.uniform(0.2, 1.0), opening=rng.uniform(0.3, 2.0))
    root_w = np.sqrt(rng.uniform(0.5, 50.0, len(points)))
    e1, e2 = np.linalg.qr(rng.normal(size=(3, 2)))[0].T
    basis = np.stack([e1, e2, np.cross(e1, e2)])
    params = np.concatenate([rng.normal(0.0, 0.1, 3), rng.normal(0.0, 0.2, 2), [rng.uniform(0.2, 1.0)]])
    return points, root_w, basis, params


def _random_2d(rng):
    n = int(rng.integers(5, 60))
    phi = np.sort(rng.uniform(0.0, rng.uniform(0.5, 3.0), n))
    radius = rng.uniform(0.2, 2.0)
    points = np.column_stack([radius * np.cos(phi), radius * np.sin(phi)]) + rng.normal(0.0, 0.002, (n, 2))
    params = np.array([*rng.normal(0.0, 0.05 * radius, 2), radius * rng.uniform(0.9, 1.1)])  # near, as the algebraic start
    return points, NO_WEIGHTS, NO_BASIS, params


@pytest.mark.parametrize("kind, make", [(CIRCLE_2D, _random_2d), (WEIGHTED_CIRCLE_3D, _random_jacobian_3d)])
def test_the_jacobian_is_the_residuals_derivative(kind, make):
    # The analytic Jacobian against central differences of the residuals at random parameters and windows.
    # Central differences with step 1e-6 carry an error of order h² f''' ~ 1e-12 plus rounding ε|f|/h ~ 1e-10
    # relative, so 1e-6 relative to the column's scale is a margin of 10⁴ that a wrong term cannot meet.
    rng = np.random.default_rng(3)
    for _ in range(20):
        points, root_w, basis, params = make(rng)
        _, jac = residuals_jacobian(kind, params, points, root_w, basis)
        numeric = np.empty_like(jac)
        for k in range(params.size):
            step = np.zeros(params.size)
            step[k] = 1e-6
            numeric[:, k] = (residuals_jacobian(kind, params + step, points, root_w, basis)[0]
                             - residuals_jacobian(kind, params - step, points, root_w, basis)[0]) / 2e-6
        np.testing.assert_allclose(jac, numeric, rtol=0, atol=1e-6 * np.abs(numeric).max())


@pytest.mark.parametrize("kind, make", [(CIRCLE_2D, _random_2d), (WEIGHTED_CIRCLE_3D, _random_3d)])
def test_it_reaches_the_minimum_minpack_reaches(kind, make):
    # From the same start, the cost at the end is no larger than MINPACK's (scipy's least_squares "lm" on
    # the same residuals and Jacobian, same tolerances) beyond 1e-9 relative, nor than the start's.
    rng = np.random.default_rng(5)
    for _ in range(30):
        points, root_w, basis, params = make(rng)
        x, r, evaluations = levenberg_marquardt(kind, params, points, root_w, basis, 1e-12, 1e-12, 1e-12, 600)
        reference = least_squares(lambda p: residuals_jacobian(kind, p, points, root_w, basis)[0], params,
                                  jac=lambda p: residuals_jacobian(kind, p, points, root_w, basis)[1], method="lm",
                                  xtol=1e-12, ftol=1e-12, gtol=1e-12)
        np.testing.assert_allclose(r, residuals_jacobian(kind, x, points, root_w, basis)[0])
        assert evaluations <= 600
        cost, best = float(r @ r), float(reference.fun @ reference.fun)
        assert cost <= float(residuals_jacobian(kind, params, points, root_w, basis)[0] @
                             residuals_jacobian(kind, params, points, root_w, basis)[0])
        assert cost <= best * (1.0 + 1e-9)


def test_a_budget_of_one_evaluation_returns_the_start():
    rng = np.random.default_rng(0)
    points, root_w, basis, params = _random_2d(rng)
    x, _, evaluations = levenberg_marquardt(CIRCLE_2D, params, points, root_w, basis, 1e-14, 1e-14, 1e-14, 1)
    assert evaluations == 1
    np.testing.assert_array_equal(x, params)
