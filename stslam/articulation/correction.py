"""A correction δ to an articulated landmark's fitted structure, and its covariance from the fit (SPEC 2, 6.3(b), 14).

The fitted structure C (:mod:`stslam.articulation.models`) is the base; δ is a
minimal correction, zero at the fit, with which a point is f(C ⊕ δ, q): a
variable of the factor graph (:mod:`stslam.graph.observing`) or a part of the
EKF state (:mod:`stslam.slam.blocks`). Only the directions q cannot absorb are corrected:

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

:func:`fit_correction_covariance` is the first-order uncertainty of δ from the
fit's points (the Cramér–Rao bound with each point's q a nuisance parameter,
as :mod:`stslam.articulation.crb` does for a planar circle) and δ's response to
a rigid error of the pose the points were mapped through.
"""

from __future__ import annotations

import numpy as np

from stslam.articulation.models import MODELS
from stslam.errors import DegenerateFitError
from stslam.geometry import cross3, rotation_about_axis, skew

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
    e1 = cross3(n, helper)
    e1 /= np.linalg.norm(e1)
    return e1, cross3(n, e1)


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


def member_corrected_position(model_name: str, founder_structure, structure, q: float, delta,
                              offset=None) -> tuple[np.ndarray, ...]:
    """A body member's f (3,), ∂f/∂q (3,), ∂f/∂δ (3, len δ) under its founder's correction δ (SPEC 6.3(b), 13),
    and with ``offset`` ε (3,) also ∂f/∂ε (3, 3).

    A member moves on its own ``structure`` in the body's q (:func:`stslam.slam.bodies.joint.member_structure`)
    and shares the founder's joint, not its offset. So it reads the part of the founder's δ that moves the
    joint, as a rigid motion of the body, and not the part that is the founder's own position:

    * prismatic: f = P0ₘ + q w, w = n̂ + u e₁ + v e₂ (the founder's tilt); the founder's (a, b) shift its
      own line only, ∂f/∂(a, b) = 0;
    * revolute: with fₘ the member's circle point and c₀ the founder's centre,
      f = c₀ + c + R(ω)(fₘ(q) − c₀): the body turns by R(ω) about c₀ and shifts by c (the founder's
      formula with (r + ρ)u replaced by the member's lever fₘ − c₀); the founder's radius ρ: ∂f/∂ρ = 0.

    For the founder itself (``structure`` = ``founder_structure``) both agree with
    :func:`corrected_position` except in (a, b) and ρ.

    ε is an error of the member's own offset, its position at q = 0 (:func:`stslam.slam.bodies.joint.member_offset`,
    a mean of its points): the member's point at q moves by ε carried with the body, R(â, q)ε about a hinge
    (then R(ω) with the body), ε along a slide. Its ∂f/∂q is taken at ε = 0 (a consider parameter stays there).
    """
    delta = np.asarray(delta, dtype=float)
    if model_name == "prismatic":
        e1, e2 = across(founder_structure.direction)
        w = founder_structure.direction + delta[2] * e1 + delta[3] * e2
        zeros = np.zeros(3)
        m, d_delta = structure.p0 + q * w, np.column_stack([zeros, zeros, q * e1, q * e2])
        if offset is None:
            return m, w, d_delta
        return m + np.asarray(offset, dtype=float), w, d_delta, np.eye(3)
    if model_name == "revolute":
        v1, v2 = founder_structure.v1, founder_structure.v2
        c0 = founder_structure.centre_world
        omega = delta[3] * v1 + delta[4] * v2
        R, Jr = _exp_and_right_jacobian(omega)
        u = np.cos(q) * structure.v1 + np.sin(q) * structure.v2
        du = -np.sin(q) * structure.v1 + np.cos(q) * structure.v2
        lever = structure.centre_world + structure.radius * u - c0
        if offset is not None:
            turn = rotation_about_axis(structure.normal, q)  # R(â, q)
            lever = lever + turn @ np.asarray(offset, dtype=float)
        m = c0 + delta[:3] + R @ lever
        d_omega = -R @ skew(lever) @ Jr @ np.column_stack([v1, v2])
        d_delta = np.column_stack([np.eye(3), d_omega, np.zeros(3)])
        if offset is None:
            return m, structure.radius * (R @ du), d_delta
        return m, structure.radius * (R @ du), d_delta, R @ turn
    raise ValueError(f"model_name: expected prismatic or revolute, got {model_name!r}")


def _tangents_and_jacobians(model_name: str, structure, q) -> tuple[np.ndarray, np.ndarray]:
    """∂f/∂q (n, 3) and ∂f/∂δ (n, 3, len δ) of :func:`corrected_position` at δ = 0 for the angles or
    travels q (n,): the line's n̂ and [e₁, e₂, q e₁, q e₂]; the circle's r(−sin q v₁ + cos q v₂) and
    [I₃, −r u × v₁, −r u × v₂, u] with u = cos q v₁ + sin q v₂ (R(0) = J_r(0) = I)."""
    q = np.asarray(q, dtype=float)
    n = q.size
    if model_name == "prismatic":
        e1, e2 = across(structure.direction)
        D = np.empty((n, 3, 4))
        D[:, :, 0], D[:, :, 1] = e1, e2
        D[:, :, 2], D[:, :, 3] = q[:, None] * e1, q[:, None] * e2
        return np.broadcast_to(structure.direction, (n, 3)), D
    v1, v2, r = structure.v1, structure.v2, structure.radius
    c, s = np.cos(q)[:, None], np.sin(q)[:, None]
    u = c * v1 + s * v2
    D = np.empty((n, 3, 6))
    D[:, :, :3] = np.eye(3)
    D[:, :, 3], D[:, :, 4], D[:, :, 5] = -r * np.cross(u, v1), -r * np.cross(u, v2), u
    return r * (-s * v1 + c * v2), D


def fit_correction_covariance(model_name: str, structure, points_world, sigma_m: float,
                              robot_xy) -> tuple[np.ndarray, np.ndarray]:
    """Covariance (p, p) of δ from the fit's points and δ's Jacobian (p, 3) on a pose error (x, y, θ).

    Points z_i = f(C ⊕ δ, q_i) + ν_i, ν_i ~ N(0, σ² I₃), each q_i unknown
    (Kay 1993, §3.9; a nuisance parameter eliminated by its Schur complement):
    with t_i = ∂f/∂q and D_i = ∂f/∂δ at δ = 0, q_i = IK(C, z_i),

        I = Σ_i D_iᵀ W_i D_i,   W_i = (I₃ − t_i t_iᵀ/‖t_i‖²)/σ²,   Σ_δ = I⁻¹.

    The points were mapped to the world through the robot's estimate
    (SPEC 5.2); a pose error e = (dx, dy, dθ) moves each by
    G_i e = [dx, dy, 0] + dθ e_z × (z_i − [x, y, 0]) about the robot position
    ``robot_xy`` (m), and the weighted least-squares fit answers with
    dδ = Σ_δ Σ_i D_iᵀ W_i G_i e. DegenerateFitError when I is singular (the
    points do not determine δ).
    """
    p = np.asarray(points_world, dtype=float).reshape(-1, 3)
    if not (np.isfinite(sigma_m) and sigma_m > 0.0):
        raise ValueError(f"sigma_m: expected a finite number > 0, got {sigma_m!r}")
    q = MODELS[model_name].motion_variable(structure, p)[:, 0]
    t, D = _tangents_and_jacobians(model_name, structure, q)  # :func:`corrected_position`'s at δ = 0, all points
    n = p.shape[0]
    W = np.eye(3) - np.einsum("ni,nj->nij", t, t) / np.einsum("ni,ni->n", t, t)[:, None, None]
    G = np.zeros((n, 3, 3))
    G[:, 0, 0] = G[:, 1, 1] = 1.0
    G[:, 0, 2], G[:, 1, 2] = -(p[:, 1] - float(robot_xy[1])), p[:, 0] - float(robot_xy[0])
    WD = W @ D
    info = np.einsum("nki,nkj->ij", D, WD)  # Σ Dᵢᵀ Wᵢ Dᵢ
    pose_rhs = np.einsum("nki,nkj->ij", WD, G)  # Σ Dᵢᵀ Wᵢ Gᵢ (W symmetric)
    if np.linalg.cond(info) > 1e12:
        raise DegenerateFitError(f"the {p.shape[0]} fitted points do not determine the {model_name} correction")
    cov = np.linalg.inv(info)
    return sigma_m ** 2 * 0.5 * (cov + cov.T), cov @ pose_rhs
