"""Cramér–Rao bounds of circle fits and the constant-rate (joint) fit (SPEC 8.1)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.articulation.crb import (crb_circle_constant_rate, crb_circle_nuisance_angles,
                               expected_abs_gaussian, expected_norm_gaussian_2d)
from stslam.articulation.circle_fit import fit_circle_constant_rate
from stslam.errors import DegenerateFitError

ANGLES = 1.5 * np.pi * np.array([0.1, 1 / 6, 0.25, 0.5, 0.6, 0.7, 0.9])


def _full_fisher_nuisance(angles, r, sigma):
    """Fisher information over (x_c, y_c, r, φ_1..φ_n), built column by column."""
    n = angles.size
    G = np.zeros((2 * n, 3 + n))
    for i, a in enumerate(angles):
        G[2 * i:2 * i + 2, 0:2] = np.eye(2)
        G[2 * i:2 * i + 2, 2] = [np.cos(a), np.sin(a)]
        G[2 * i:2 * i + 2, 3 + i] = r * np.array([-np.sin(a), np.cos(a)])
    return G.T @ G / sigma ** 2


@pytest.mark.parametrize("r", [0.3, 1.0, 4.0])
def test_nuisance_bound_is_the_block_of_the_full_inverse(r):
    # the closed form σ²(Σ w wᵀ)⁻¹ must equal the (c, r) block of the full J⁻¹, for any r
    full = np.linalg.inv(_full_fisher_nuisance(ANGLES, r, 0.1))[:3, :3]
    assert np.allclose(crb_circle_nuisance_angles(ANGLES, 0.1), full, rtol=1e-9, atol=1e-14)


def test_full_circle_bound_closed_form():
    # n evenly spaced angles over 2π: Σ w wᵀ = diag(n/2, n/2, n), so CRB = σ² diag(2/n, 2/n, 1/n)
    n, sigma = 12, 0.2
    crb = crb_circle_nuisance_angles(2 * np.pi * np.arange(n) / n, sigma)
    assert np.allclose(crb, sigma ** 2 * np.diag([2 / n, 2 / n, 1 / n]), atol=1e-15)


def test_constant_rate_bound_is_tighter_than_nuisance_bound():
    t = np.arange(10.0)
    angles = 0.3 + 0.25 * t
    joint = crb_circle_constant_rate(angles, t, 1.0, 0.1)[:3, :3]
    separate = crb_circle_nuisance_angles(angles, 0.1)
    # knowing the timing adds information: separate − joint is positive semi-definite
    assert np.linalg.eigvalsh(separate - joint).min() > -1e-15
    assert np.trace(joint) < np.trace(separate)


def test_bound_matches_monte_carlo_of_the_constant_rate_fit():
    # 180° in 20 steps, σ = 0.05: high SNR, so the ML fit is efficient. With 400 runs the
    # sample variance of each coordinate has relative SE √(2/399) ≈ 7%; allow 4 SE = 28%.
    rng = np.random.default_rng(21)
    t = np.arange(20.0)
    angles = np.pi * t / 19
    truth = np.array([2.0, 2.0])
    crb = crb_circle_constant_rate(angles, t, 1.0, 0.05)
    estimates = []
    for _ in range(400):
        z = truth + np.column_stack([np.cos(angles), np.sin(angles)]) + rng.normal(0, 0.05, (20, 2))
        c, r, th0, om = fit_circle_constant_rate(z, t)
        estimates.append([c[0], c[1], r, th0, om])
    var = np.var(np.array(estimates), axis=0, ddof=1)
    assert np.allclose(var, np.diag(crb), rtol=0.28)


def test_expected_norms():
    s = 0.3
    assert expected_norm_gaussian_2d(np.eye(2) * s ** 2) == pytest.approx(s * np.sqrt(np.pi / 2), rel=1e-12)
    assert expected_norm_gaussian_2d(np.diag([s ** 2, 0.0])) == pytest.approx(s * np.sqrt(2 / np.pi), rel=1e-12)
    assert expected_abs_gaussian(s ** 2) == pytest.approx(s * np.sqrt(2 / np.pi), rel=1e-12)
    # anisotropic case against a seeded Monte Carlo: 200k draws, SE of the mean ≈ 0.6/√2e5 ≈ 1.3e-3
    cov = np.array([[0.5, 0.2], [0.2, 0.1]])
    e = np.random.default_rng(2).multivariate_normal([0, 0], cov, 200_000)
    assert expected_norm_gaussian_2d(cov) == pytest.approx(np.linalg.norm(e, axis=1).mean(), abs=4 * 1.3e-3)


def test_constant_rate_fit_recovers_noise_free_motion():
    t = np.array([0.0, 1.0, 2.0, 3.5, 5.0])
    theta0, omega, r, c = 2.9, -0.45, 0.7, np.array([-1.0, 3.0])  # clockwise, crossing ±π
    a = theta0 + omega * t
    z = c + r * np.column_stack([np.cos(a), np.sin(a)])
    c_hat, r_hat, th_hat, om_hat = fit_circle_constant_rate(z, t)
    assert np.allclose(c_hat, c, atol=1e-9) and r_hat == pytest.approx(r, abs=1e-9)
    assert om_hat == pytest.approx(omega, abs=1e-9)
    assert np.cos(th_hat - theta0) == pytest.approx(1.0, abs=1e-12)


def test_degenerate_inputs_raise():
    with pytest.raises(DegenerateFitError, match="Fisher information is singular"):
        crb_circle_nuisance_angles([0.5, 0.5, 0.5], 0.1)
    with pytest.raises(DegenerateFitError, match="at least 3 distinct points"):
        fit_circle_constant_rate([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0]], [0.0, 1.0, 2.0])
    with pytest.raises(ValueError, match="times_s must be 3 finite values"):
        fit_circle_constant_rate([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], [0.0, 1.0])
    with pytest.raises(ValueError, match="sigma_m: expected a finite number > 0"):
        crb_circle_nuisance_angles(ANGLES, 0.0)
