"""Cramér–Rao bounds for a circle observed with isotropic Gaussian noise (SPEC 8.1).

Observation model: z_i = c + r·u(φ_i) + ν_i, ν_i ~ N(0, σ² I₂), with
u(φ) = [cos φ, sin φ] and τ(φ) = [−sin φ, cos φ] = du/dφ. For Gaussian noise
with a mean μ(θ), the Fisher information is J = (1/σ²) Σ_i G_iᵀ G_i with
G_i = ∂μ_i/∂θ (Kay, *Fundamentals of Statistical Signal Processing I*, §3.9);
the bound on any unbiased estimator is cov(θ̂) ⪰ J⁻¹.

Two parametrisations, matching the two estimators of SPEC 8.1:

* **Angles as nuisance parameters** (the "separate" circle fit does not know
  when each point was taken): θ = (x_c, y_c, r, φ_1 … φ_n). Per point,
  G_i = [I₂ | u_i | r τ_i] (the r τ_i column sits in φ_i's slot). The φ block of
  J is diagonal (r²/σ²), so eliminating it with a Schur complement leaves, per
  point, (1/σ²) A_iᵀ (I₂ − τ_i τ_iᵀ) A_i with A_i = [I₂ | u_i]; since
  I₂ − τ_i τ_iᵀ = u_i u_iᵀ this is (1/σ²) w_i w_iᵀ with w_i = A_iᵀ u_i =
  [cos φ_i, sin φ_i, 1]. Hence

      CRB(x_c, y_c, r) = σ² ( Σ_i w_i w_iᵀ )⁻¹,

  which does not depend on r (the classic result for circle fitting, e.g.
  Chan & Thomas 1995). Only the radial component of the noise carries
  information about (c, r); the tangential part is spent on the unknown angles.

* **Constant rate** (the "joint" fit, φ_i = θ0 + ω t_i, correctly specified only
  when the samples really are evenly turned): θ = (x_c, y_c, r, θ0, ω),
  G_i = [I₂ | u_i | r τ_i | r t_i τ_i]; the bound is the (c, r) block of J⁻¹.
  It is never larger than the nuisance-angle bound: knowing the timing adds
  information.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ellipe

from stslam.errors import DegenerateFitError


def _check(angles_rad, sigma_m) -> np.ndarray:
    phi = np.asarray(angles_rad, dtype=float).reshape(-1)
    if not np.all(np.isfinite(phi)):
        raise ValueError("angles_rad contains non-finite values")
    if not (np.isfinite(sigma_m) and sigma_m > 0.0):
        raise ValueError(f"sigma_m: expected a finite number > 0, got {sigma_m!r}")
    return phi


def _inverse(J: np.ndarray, what: str) -> np.ndarray:
    if np.linalg.cond(J) > 1e12:
        raise DegenerateFitError(f"{what}: Fisher information is singular (condition {np.linalg.cond(J):.3g}); "
                                 "the sample angles do not determine the circle")
    return np.linalg.inv(J)


def crb_circle_nuisance_angles(angles_rad, sigma_m: float) -> np.ndarray:
    """CRB of (x_c, y_c, r) when every sample angle is unknown, shape (3, 3), m².

    CRB = σ² (Σ_i w_i w_iᵀ)⁻¹ with w_i = [cos φ_i, sin φ_i, 1] (derivation in
    the module docstring).

    Parameters
    ----------
    angles_rad : array_like, shape (n,)
        True sample angles φ_i about the centre (rad); n ≥ 3, not all equal
        modulo 2π.
    sigma_m : float
        Standard deviation of the noise on each coordinate (m).
    """
    phi = _check(angles_rad, sigma_m)
    w = np.column_stack([np.cos(phi), np.sin(phi), np.ones_like(phi)])
    return sigma_m ** 2 * _inverse(w.T @ w, "circle CRB")


def crb_circle_constant_rate(angles_rad, times_s, radius_m: float, sigma_m: float) -> np.ndarray:
    """CRB of (x_c, y_c, r, θ0, ω) for a point turning at constant rate, shape (5, 5).

    J = (1/σ²) Σ_i G_iᵀ G_i, G_i = [I₂ | u_i | r τ_i | r t_i τ_i] at the true
    angles φ_i = θ0 + ω t_i (module docstring); units m², m·rad, rad², rad²/s².

    Parameters
    ----------
    angles_rad : array_like, shape (n,)
        True angles θ0 + ω t_i (rad).
    times_s : array_like, shape (n,)
        Sample times t_i (s, or sample index).
    radius_m : float
        True radius r (m).
    sigma_m : float
        Noise standard deviation per coordinate (m).
    """
    phi = _check(angles_rad, sigma_m)
    t = np.asarray(times_s, dtype=float).reshape(-1)
    if t.shape != phi.shape:
        raise ValueError(f"times_s must have shape {phi.shape}, got {t.shape}")
    u = np.column_stack([np.cos(phi), np.sin(phi)])
    tau = np.column_stack([-np.sin(phi), np.cos(phi)])
    G = np.zeros((phi.size, 2, 5))
    G[:, :, 0:2] = np.eye(2)
    G[:, :, 2] = u
    G[:, :, 3] = radius_m * tau
    G[:, :, 4] = radius_m * t[:, None] * tau
    J = np.einsum("nki,nkj->ij", G, G) / sigma_m ** 2
    return _inverse(J, "constant-rate circle CRB")


def expected_norm_gaussian_2d(cov) -> float:
    """E‖e‖ for e ~ N(0, cov), cov of shape (2, 2) (m² → m).

    With eigenvalues λ1 ≥ λ2 of cov: E‖e‖ = √(2λ1/π) · E(1 − λ2/λ1), E the
    complete elliptic integral of the second kind (parameter m). Checks:
    λ1 = λ2 = s² gives the Rayleigh mean s√(π/2); λ2 = 0 the half-normal mean
    s√(2/π). It is the mean centre error of an efficient estimator, the value
    reported beside the measured mean ``centre_error``.
    """
    lam = np.linalg.eigvalsh(np.asarray(cov, dtype=float))
    lam1, lam2 = max(lam[1], 0.0), max(lam[0], 0.0)
    if lam1 == 0.0:
        return 0.0
    return float(np.sqrt(2.0 * lam1 / np.pi) * ellipe(1.0 - lam2 / lam1))


def expected_abs_gaussian(variance) -> float:
    """E|e| = σ√(2/π) for e ~ N(0, σ²) (m² → m): the half-normal mean."""
    return float(np.sqrt(2.0 * max(float(variance), 0.0) / np.pi))
