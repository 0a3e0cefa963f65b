"""An articulated landmark's structure as a graph variable: a correction δ to the fitted structure (SPEC 2, 14).

The fitted structure C (:mod:`stslam.articulation.models`) is the base; the
variable is a minimal correction δ, zero at the fit, with which a member
point is f(C ⊕ δ, q). Only the directions q cannot absorb are corrected:

* prismatic (SPEC 2.2), δ = (a, b, u, v) (m, m, 1, 1): with e₁, e₂ an
  orthonormal pair across n̂, P0′ = P0 + a e₁ + b e₂ and w = n̂ + u e₁ + v e₂;
  f = P0′ + l w (a shift along n̂ is a shift of l). The line's direction is
  w/‖w‖ and l the travel along n̂; w is not normalised, so that f is linear in
  δ for a fixed l and in l for a fixed δ. With n̂′ = w/‖w‖ instead, ∂f/∂(u, v)
  would shrink as 1/‖w‖² while the tilt grows: where few observations span
  little of the line the tilt is barely observed, and iSAM2's Gauss-Newton
  steps, each larger as that derivative shrinks, run away;
* revolute (SPEC 2.3), δ = (c (3), α, β, ρ) (m, rad, m): the circle's centre
  moves by c, its plane turns by R(ω) = exp([ω]×), ω = α v₁ + β v₂ (a turn
  about the normal is a shift of φ), its radius becomes r + ρ;
  f = c₀ + c + (r + ρ) R(ω)(cos φ v₁ + sin φ v₂).

:func:`corrected_position` returns f with ∂f/∂q and ∂f/∂δ; the revolute
∂/∂ω uses the right Jacobian of SO(3), R(ω + dω) ≈ R(ω) exp([J_r(ω) dω]×)
(Barfoot 2017, §7.1.5: ∂(R(ω)u)/∂ω = −R(ω)[u]× J_r(ω)).
"""

from __future__ import annotations

import numpy as np

from stslam.geometry import skew

SIZES = {"prismatic": 4, "revolute": 6}


def correction_size(model_name: str) -> int:
    """Length of δ for ``model_name`` (prismatic 4, revolute 6); ValueError for another model."""
    if model_name not in SIZES:
        raise ValueError(f"model_name: expected prismatic or revolute, got {model_name!r}")
    return SIZES[model_name]


def across(direction) -> tuple[np.ndarray, np.ndarray]:
    """An orthonormal pair (e₁, e₂) across the unit ``direction`` (3,), the same for the same direction."""
    n = np.asarray(direction, dtype=float)
    helper = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = np.cross(n, helper)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(n, e1)


def _exp_and_right_jacobian(omega) -> tuple[np.ndarray, np.ndarray]:
    """R = exp([ω]×) and J_r(ω) = I − (1 − cos θ)/θ² [ω]× + (θ − sin θ)/θ³ [ω]×² (Barfoot 2017, Eq. 7.77)."""
    theta = float(np.linalg.norm(omega))
    K = skew(omega)
    if theta < 1e-6:  # second-order series of both
        return np.eye(3) + K + 0.5 * K @ K, np.eye(3) - 0.5 * K + K @ K / 6.0
    a, b = np.sin(theta) / theta, (1.0 - np.cos(theta)) / theta**2
    c = (theta - np.sin(theta)) / theta**3
    return np.eye(3) + a * K + b * K @ K, np.eye(3) - b * K + c * K @ K


def corrected_position(model_name: str, structure, q: float, delta) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """f(C ⊕ δ, q) (3,), ∂f/∂q (3,) and ∂f/∂δ (3, len δ) (module docstring)."""
    delta = np.asarray(delta, dtype=float)
    if model_name == "prismatic":
        n = structure.direction
        e1, e2 = across(n)
        a, b, u, v = delta
        w = n + u * e1 + v * e2
        m = structure.p0 + a * e1 + b * e2 + q * w
        return m, w, np.column_stack([e1, e2, q * e1, q * e2])
    if model_name == "revolute":
        v1, v2 = structure.v1, structure.v2
        c, omega_ab, rho = delta[:3], delta[3:5], delta[5]
        omega = omega_ab[0] * v1 + omega_ab[1] * v2
        R, Jr = _exp_and_right_jacobian(omega)
        u = np.cos(q) * v1 + np.sin(q) * v2
        du = -np.sin(q) * v1 + np.cos(q) * v2
        radius = structure.radius + rho
        m = structure.centre_world + c + radius * (R @ u)
        d_omega = -radius * R @ skew(u) @ Jr @ np.column_stack([v1, v2])
        return m, radius * (R @ du), np.column_stack([np.eye(3), d_omega, R @ u])
    raise ValueError(f"model_name: expected prismatic or revolute, got {model_name!r}")
