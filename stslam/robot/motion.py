"""Planar robot: velocity motion model, its Jacobians and control noise (SPEC 5.1, paper §VI-A).

Pose ``pose_xytheta`` = (x m, y m, θ rad) in the world frame; control
``control_vw`` = (v m/s, ω rad/s) held for one step of δt seconds (one frame
in the simulated worlds, δt = 1). The robot drives on an arc of radius v/ω,
or straight when |ω| ≤ ε (the arc formula divides by ω).
"""

from __future__ import annotations

import numpy as np

# Angular speed below which the straight-line branch is used (rad/s); SPEC 5.1's ε.
OMEGA_EPS = 1e-9


def wrap_angle(angle_rad):
    """Angle(s) wrapped to [−π, π)."""
    return (np.asarray(angle_rad, dtype=float) + np.pi) % (2.0 * np.pi) - np.pi


def _check_pose(pose_xytheta) -> np.ndarray:
    pose = np.asarray(pose_xytheta, dtype=float)
    if pose.shape != (3,):
        raise ValueError(f"pose_xytheta must have shape (3,), got {pose.shape}")
    return pose


def _check_control(control_vw) -> np.ndarray:
    u = np.asarray(control_vw, dtype=float)
    if u.shape != (2,):
        raise ValueError(f"control_vw must have shape (2,), got {u.shape}")
    return u


def check_alpha(alpha) -> np.ndarray:
    """The four control-noise coefficients α (SPEC 5.1) as a float array, each ≥ 0."""
    a = np.asarray(alpha, dtype=float)
    if a.shape != (4,) or not np.all(np.isfinite(a)) or np.any(a < 0):
        raise ValueError(f"alpha: expected 4 numbers ≥ 0, got {alpha!r}")
    return a


def move(pose_xytheta, control_vw, dt: float, eps: float = OMEGA_EPS) -> np.ndarray:
    """Pose after one step of the velocity motion model (SPEC 5.1).

    |ω| > ε:  x' = x − (v/ω) sin θ + (v/ω) sin(θ + ωδt),
              y' = y + (v/ω) cos θ − (v/ω) cos(θ + ωδt),  θ' = θ + ωδt;
    |ω| ≤ ε:  x' = x + vδt cos θ,  y' = y + vδt sin θ,  θ' = θ.

    Parameters
    ----------
    pose_xytheta : array_like, shape (3,)
        (x m, y m, θ rad), world frame.
    control_vw : array_like, shape (2,)
        (v m/s, ω rad/s).
    dt : float
        Step length δt (s).

    Returns
    -------
    numpy.ndarray, shape (3,)
        The new pose; θ' is not wrapped (filters wrap differences, not states).
    """
    x, y, theta = _check_pose(pose_xytheta)
    v, w = _check_control(control_vw)
    if abs(w) > eps:
        ratio = v / w
        theta_new = theta + w * dt
        return np.array([
            x - ratio * np.sin(theta) + ratio * np.sin(theta_new),
            y + ratio * np.cos(theta) - ratio * np.cos(theta_new),
            theta_new,
        ])
    return np.array([x + v * dt * np.cos(theta), y + v * dt * np.sin(theta), theta])


def motion_jacobians(pose_xytheta, control_vw, dt: float,
                     eps: float = OMEGA_EPS) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians of :func:`move`: G = ∂x'/∂x (3, 3) and V = ∂x'/∂u (3, 2) (SPEC 5.1).

    Arc branch (|ω| > ε), with θ' = θ + ωδt:
        G[0, 2] = −(v/ω) cos θ + (v/ω) cos θ',  G[1, 2] = −(v/ω) sin θ + (v/ω) sin θ';
        V[:, 0] = ((sin θ' − sin θ)/ω, (cos θ − cos θ')/ω, 0);
        V[:, 1] = (v(sin θ − sin θ')/ω² + v δt cos θ'/ω,
                   −v(cos θ − cos θ')/ω² + v δt sin θ'/ω,  δt).
    Straight branch (|ω| ≤ ε):
        G[0, 2] = −vδt sin θ,  G[1, 2] = vδt cos θ;
        V[:, 0] = (δt cos θ, δt sin θ, 0);  V[:, 1] = (−vδt² sin θ / 2, vδt² cos θ / 2, δt),
    the ω → 0 limit of the arc branch (so V is continuous across the switch).
    """
    _, _, theta = _check_pose(pose_xytheta)
    v, w = _check_control(control_vw)
    G = np.eye(3)
    V = np.zeros((3, 2))
    V[2, 1] = dt
    if abs(w) > eps:
        theta_new = theta + w * dt
        s0, c0, s1, c1 = np.sin(theta), np.cos(theta), np.sin(theta_new), np.cos(theta_new)
        ratio = v / w
        G[0, 2] = -ratio * c0 + ratio * c1
        G[1, 2] = -ratio * s0 + ratio * s1
        V[0, 0] = (s1 - s0) / w
        V[1, 0] = (c0 - c1) / w
        V[0, 1] = v * (s0 - s1) / w**2 + v * dt * c1 / w
        V[1, 1] = -v * (c0 - c1) / w**2 + v * dt * s1 / w
    else:
        s0, c0 = np.sin(theta), np.cos(theta)
        G[0, 2] = -v * dt * s0
        G[1, 2] = v * dt * c0
        V[0, 0] = dt * c0
        V[1, 0] = dt * s0
        V[0, 1] = -0.5 * v * dt**2 * s0
        V[1, 1] = 0.5 * v * dt**2 * c0
    return G, V


def motion_control_hessians(pose_xytheta, control_vw, dt: float, eps: float = OMEGA_EPS) -> np.ndarray:
    """Second derivatives ∂²x'ᵢ/∂u∂u of :func:`move` in the control u = (v, ω), shape (3, 2, 2).

    x' is linear in v, so ∂²/∂v² = 0; θ' is linear in u, so its Hessian is 0.
    Arc branch (|ω| > ε), θ' = θ + ωδt, Δs = sin θ' − sin θ, Δc = cos θ − cos θ':
        ∂²x'/∂v∂ω = −Δs/ω² + δt cos θ'/ω,   ∂²x'/∂ω² = v(2Δs/ω³ − 2δt cos θ'/ω² − δt² sin θ'/ω),
        ∂²y'/∂v∂ω = −Δc/ω² + δt sin θ'/ω,   ∂²y'/∂ω² = v(2Δc/ω³ − 2δt sin θ'/ω² + δt² cos θ'/ω).
    Straight branch (|ω| ≤ ε), the ω → 0 limits of the same:
        ∂²x'/∂v∂ω = −δt² sin θ/2,  ∂²x'/∂ω² = −vδt³ cos θ/3,
        ∂²y'/∂v∂ω = δt² cos θ/2,   ∂²y'/∂ω² = −vδt³ sin θ/3.
    """
    _, _, theta = _check_pose(pose_xytheta)
    v, w = _check_control(control_vw)
    hess = np.zeros((3, 2, 2))
    if abs(w) > eps:
        theta_new = theta + w * dt
        s0, c0, s1, c1 = np.sin(theta), np.cos(theta), np.sin(theta_new), np.cos(theta_new)
        ds, dc = s1 - s0, c0 - c1
        vw = (-ds / w**2 + dt * c1 / w, -dc / w**2 + dt * s1 / w)
        ww = (v * (2 * ds / w**3 - 2 * dt * c1 / w**2 - dt**2 * s1 / w),
              v * (2 * dc / w**3 - 2 * dt * s1 / w**2 + dt**2 * c1 / w))
    else:
        s0, c0 = np.sin(theta), np.cos(theta)
        vw = (-0.5 * dt**2 * s0, 0.5 * dt**2 * c0)
        ww = (-v * dt**3 * c0 / 3.0, -v * dt**3 * s0 / 3.0)
    for i in range(2):
        hess[i, 0, 1] = hess[i, 1, 0] = vw[i]
        hess[i, 1, 1] = ww[i]
    return hess


def second_order_motion_noise(pose_xytheta, control_vw, control_cov, dt: float) -> np.ndarray:
    """Second-order part of the pose covariance the control noise causes, shape (3, 3).

    For u ~ N(û, S) through x' = f(x, u), the covariance of x' to second order
    is V S Vᵀ + Q₂ with Q₂[i, j] = ½ tr(Hᵢ S Hⱼ S), Hᵢ = ∂²x'ᵢ/∂u² (the
    second-order EKF, Bar-Shalom, Li, Kirubarajan 2001, §10.3; SPEC 5.1's
    model). Two controls drive three pose states, so V S Vᵀ alone has rank 2:
    it claims the next pose lies exactly on a plane, while the true poses lie
    on a curved surface (the v·ω cross term moves them off it by about
    δt² σ_v σ_ω / 2). Q₂ gives that direction its variance.
    """
    hess = motion_control_hessians(pose_xytheta, control_vw, dt)
    hs = hess @ np.asarray(control_cov, dtype=float)  # Hᵢ S, (3, 2, 2)
    return 0.5 * np.einsum("iab,jba->ij", hs, hs)  # ½ tr(Hᵢ S Hⱼ S)


def control_noise_cov(control_vw, alpha) -> np.ndarray:
    """Control noise covariance S = diag(α1 v² + α2 ω², α3 v² + α4 ω²), shape (2, 2) (SPEC 5.1).

    Units: (m/s)² and (rad/s)²; α mixes them as in the paper (Thrun et al.'s
    odometry-noise convention).
    """
    v, w = _check_control(control_vw)
    a = check_alpha(alpha)
    return np.diag([a[0] * v**2 + a[1] * w**2, a[2] * v**2 + a[3] * w**2])


def sample_noisy_controls(controls_vw, alpha, rng: np.random.Generator) -> np.ndarray:
    """Controls disturbed by N(0, S(u)) for each row (SPEC 5.1).

    Parameters
    ----------
    controls_vw : array_like, shape (n, 2)
        Controls (v m/s, ω rad/s), one per step.
    alpha : array_like, shape (4,)
    rng : numpy.random.Generator
        Draws exactly ``2 n`` standard normals, row by row.

    Returns
    -------
    numpy.ndarray, shape (n, 2)
    """
    u = np.asarray(controls_vw, dtype=float)
    if u.ndim != 2 or u.shape[1] != 2:
        raise ValueError(f"controls_vw must have shape (n, 2), got {u.shape}")
    a = check_alpha(alpha)
    std = np.sqrt(np.column_stack([a[0] * u[:, 0]**2 + a[1] * u[:, 1]**2,
                                   a[2] * u[:, 0]**2 + a[3] * u[:, 1]**2]))
    return u + std * rng.standard_normal(u.shape)


def control_between(pose_from, pose_to, dt: float, eps: float = OMEGA_EPS) -> np.ndarray:
    """The control (v, ω) that :func:`move` turns ``pose_from`` into ``pose_to`` with (SPEC 5.1 inverted).

    ω = wrap(θ' − θ)/δt. On an arc of turn Δθ = ωδt the chord d joins the two
    positions in the direction θ + Δθ/2 and has length 2|v/ω| |sin(Δθ/2)|, so
    v = (chord · heading(θ + Δθ/2)) · ω / (2 sin(Δθ/2)); straight: v = (chord ·
    heading θ)/δt. Exact when the two poses lie on one arc tangent to the first
    heading (as in every simulated trajectory); otherwise the least-squares
    projection of the chord on that arc's direction.
    """
    p0 = _check_pose(pose_from)
    p1 = _check_pose(pose_to)
    turn = float(wrap_angle(p1[2] - p0[2]))
    w = turn / dt
    chord = p1[:2] - p0[:2]
    if abs(w) > eps:
        mid = p0[2] + 0.5 * turn
        along = chord[0] * np.cos(mid) + chord[1] * np.sin(mid)
        v = along * w / (2.0 * np.sin(0.5 * turn))
    else:
        v = (chord[0] * np.cos(p0[2]) + chord[1] * np.sin(p0[2])) / dt
    return np.array([v, w])
