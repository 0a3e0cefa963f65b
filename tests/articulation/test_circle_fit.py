"""Circle fits (SPEC 2.3, 2.4): exact recovery, noise behaviour, degenerate inputs."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.articulation.circle_fit import (circle_residuals, fit_circle, fit_circle_algebraic,
                               fit_circle_geometric)
from stslam.errors import DegenerateFitError


def _arc(centre, radius, angles):
    return np.column_stack([centre[0] + radius * np.cos(angles), centre[1] + radius * np.sin(angles)])


@pytest.mark.parametrize("fit", [fit_circle_algebraic, fit_circle_geometric, fit_circle])
@pytest.mark.parametrize("centre, radius, angles", [
    ((2.0, 2.0), 1.0, 1.5 * np.pi * np.array([0.1, 1 / 6, 0.25, 0.5, 0.6, 0.7, 0.9])),
    ((-30.0, 7.5), 0.25, np.array([0.3, 0.35, 0.5, 0.52])),   # short lopsided arc, far from origin
    ((1e3, -1e3), 40.0, np.array([-2.0, 1.0, 2.5])),          # exactly 3 points
])
def test_noise_free_points_give_the_circle_back(fit, centre, radius, angles):
    c, r = fit(_arc(centre, radius, angles))
    # noise-free data: only round-off remains (relative 1e-9 of the scale)
    scale = max(radius, np.abs(centre).max())
    assert np.allclose(c, centre, atol=1e-9 * scale)
    assert r == pytest.approx(radius, abs=1e-9 * scale)


def test_geometric_fit_minimises_orthogonal_distances():
    rng = np.random.default_rng(3)
    p = _arc((0.5, -1.0), 2.0, rng.uniform(0.0, 1.5, 12)) + rng.normal(0.0, 0.05, (12, 2))
    c, r = fit_circle_geometric(p)
    cost = np.sum(circle_residuals(p, c, r) ** 2)
    # a stationary point: every small perturbation of (c, r) raises the cost
    for step in np.eye(3) * 1e-4:
        for sign in (-1.0, 1.0):
            cost_moved = np.sum(circle_residuals(p, c + sign * step[:2], r + sign * step[2]) ** 2)
            assert cost_moved > cost
    # and the algebraic start is no better than the refinement
    ca, ra = fit_circle_algebraic(p)
    assert np.sum(circle_residuals(p, ca, ra) ** 2) >= cost


def test_taubin_beats_kasa_bias_on_short_arcs():
    # Kåsa's fit shrinks the radius on short noisy arcs; Taubin's should be much closer
    # to unbiased. 400 runs of r = 1, arc 60°, σ = 0.02: the Kåsa bias is several σ_mean.
    rng = np.random.default_rng(11)
    angles = np.linspace(0.0, np.pi / 3, 15)
    taubin, kasa = [], []
    for _ in range(400):
        p = _arc((0.0, 0.0), 1.0, angles) + rng.normal(0.0, 0.02, (15, 2))
        taubin.append(fit_circle_algebraic(p)[1])
        a = np.column_stack([p, np.ones(15)])
        sol = np.linalg.lstsq(a, np.sum(p * p, axis=1), rcond=None)[0]
        kasa.append(np.sqrt(sol[2] + sol[0] ** 2 / 4 + sol[1] ** 2 / 4))
    assert abs(np.mean(taubin) - 1.0) < 0.5 * abs(np.mean(kasa) - 1.0)


@pytest.mark.parametrize("points, match", [
    (np.array([[0.0, 0.0], [1.0, 1.0]]), "at least 3 distinct points"),
    (np.array([[0.0, 0.0], [1.0, 1.0], [1.0, 1.0], [0.0, 0.0]]), "at least 3 distinct points"),
    (np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0], [-3.0, -3.0]]), "collinear"),
])
@pytest.mark.parametrize("fit", [fit_circle_algebraic, fit_circle_geometric])
def test_degenerate_points_raise(points, match, fit):
    with pytest.raises(DegenerateFitError, match=match):
        fit(points)


@pytest.mark.parametrize("bad, match", [
    (np.zeros((4, 3)), r"shape \(n, 2\)"),
    (np.array([[0.0, np.nan], [1.0, 0.0], [0.0, 1.0]]), "non-finite"),
])
def test_bad_arrays_raise(bad, match):
    with pytest.raises(ValueError, match=match):
        fit_circle(bad)


def test_distinct_rows_upto_matches_numpy_unique():
    # The fits' count of distinct rows (compiled, stopping at k) against numpy's, capped at k.
    from stslam.articulation.circle_kernels import distinct_rows_upto

    rng = np.random.default_rng(3)
    for n, d in ((1, 2), (7, 2), (40, 3)):
        p = rng.integers(0, 3, size=(n, d)).astype(float)  # few values: many repeated rows
        for k in (2, 3, 30):
            assert distinct_rows_upto(p, k) == min(np.unique(p, axis=0).shape[0], k)
    assert distinct_rows_upto(np.empty((0, 3)), 3) == 0
    assert distinct_rows_upto(np.array([[0.0, 1.0], [-0.0, 1.0]]), 3) == 1  # −0 and 0 are one value, as in np.unique


def _least_squares_fit(points_xy):
    """The straightforward route: SciPy's least_squares(method="lm") from the algebraic start, in normalised units."""
    from scipy.optimize import least_squares
    p = np.asarray(points_xy, dtype=float)
    m = p.mean(axis=0)
    s = float(np.sqrt(np.mean(np.sum((p - m) ** 2, axis=1))))
    u = (p - m) / s
    c0, r0 = fit_circle_algebraic(p)
    start = np.concatenate([(c0 - m) / s, [r0 / s]])

    def residual(theta):
        return np.linalg.norm(u - theta[:2], axis=1) - theta[2]

    def jacobian(theta):
        d = u - theta[:2]
        dist = np.maximum(np.linalg.norm(d, axis=1), np.finfo(float).tiny)
        return np.column_stack([-d / dist[:, None], -np.ones(u.shape[0])])

    theta = least_squares(residual, start, jac=jacobian, method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14).x
    return m + s * theta[:2], s * abs(float(theta[2]))


def test_fit_circle_equals_least_squares_from_the_algebraic_start():
    rng = np.random.default_rng(7)
    for _ in range(100):
        n = int(rng.integers(5, 80))
        arc, radius = rng.uniform(0.3, 3.0), rng.uniform(0.1, 2.0)
        p = _arc((0.3, -0.7), radius, np.linspace(0.0, arc, n)) + rng.normal(0.0, rng.choice([1e-4, 2e-3]), (n, 2))
        c, r = fit_circle(p)
        c_ref, r_ref = _least_squares_fit(p)
        # The same least-squares minimum by another Levenberg–Marquardt (stslam.articulation.small_lm): the cost
        # to round-off, the circle to 1e-7 of its radius (on a short arc the cost is flat along the axis of
        # symmetry, where stopping at ftol = 1e-14 leaves ~√1e-14 of relative freedom)
        cost, cost_ref = np.sum(circle_residuals(p, c, r) ** 2), np.sum(circle_residuals(p, c_ref, r_ref) ** 2)
        assert cost == pytest.approx(cost_ref, rel=1e-11)
        np.testing.assert_allclose(c, c_ref, rtol=0, atol=1e-7 * r_ref)
        assert r == pytest.approx(r_ref, rel=1e-7)
