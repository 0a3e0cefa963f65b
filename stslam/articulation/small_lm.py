"""Compiled Levenberg–Marquardt for the two small circle fits (SPEC 2.3, SPEC 18).

Both circle fits of the library are nonlinear least squares with 3 or 6 parameters on a few tens
of points, solved many times per track (every structure refit, every window's evidence). Through
MINPACK each call spent most of its time in Python callbacks; here the residuals, their analytic
Jacobian and the iteration are one compiled kernel (numba, compiled once and cached on disk).

The iteration (Marquardt's, with Nielsen's damping update): with r(x) the residuals, J = ∂r/∂x,
A = JᵀJ, g = Jᵀr and D the running maximum of the column norms of J (MINPACK's scaling),

    (A + λ D²) h = −g,     ρ = (‖r(x)‖² − ‖r(x + h)‖²) / (‖r(x)‖² − ‖r(x) + J h‖²)

a step with ρ > 0 is taken and λ ← λ·max(1/3, 1 − (2ρ − 1)³), ν ← 2; otherwise λ ← λ·ν, ν ← 2ν.
A step longer (‖D h‖) than a trust radius Δ is damped further before it is tried: Δ starts at
``TRUST_FACTOR``·‖D x₀‖, halves to below a rejected step and grows to 3‖D h‖ after a step with ρ > 0.75
(so that a Gauss–Newton step cannot run off along a flat direction, a circle's radius on a short arc).
It stops as MINPACK's lmder does: the actual and predicted relative reductions of ‖r‖² are both
at most ``ftol``; the scaled step ‖D h‖ is at most ``xtol``·‖D x‖; the largest cosine between r
and a column of J is at most ``gtol``; or ``max_evaluations`` residual evaluations were spent
(then the best point so far is returned).

Residual kinds (:data:`CIRCLE_2D`, :data:`WEIGHTED_CIRCLE_3D`):

* 2D orthogonal distances r_i = ‖u_i − c‖ − R of points u (n, 2), parameters (c (2), R)
  (:func:`stslam.articulation.circle_fit.fit_circle_geometric`);
* 3D weighted (height, radial) distances to a circle whose plane normal is n0 = e1 × e2 tilted
  by (t1, t2) along e1, e2 (:func:`stslam.articulation.window_evidence.revolute_log_odds`):
  parameters (c (3), t1, t2, R), residuals √w_i·h_i (first n) and √w_i·(ρ_i − R) (last n),
  with d = p − c, n = (n0 + t1 e1 + t2 e2)/ℓ, h = d·n, ρ = √(|d|² − h²).
"""

from __future__ import annotations

import numpy as np
from numba import njit

CIRCLE_2D = 0
WEIGHTED_CIRCLE_3D = 1
TRUST_FACTOR = 100.0  # the first step is at most this times ‖D x₀‖ (MINPACK's ``factor``)


@njit(cache=True)
def residuals_jacobian(kind, x, points, root_w, basis):
    """Residuals (m,) and Jacobian (m, p) of residual kind ``kind`` (module docstring) at ``x``.

    ``basis`` (3, 3): rows e1, e2, n0 (3D kind only); ``root_w`` (n,): √w (3D kind only).
    """
    n = points.shape[0]
    if kind == CIRCLE_2D:
        r = np.empty(n)
        J = np.empty((n, 3))
        tiny = np.finfo(np.float64).tiny
        for i in range(n):
            dx, dy = points[i, 0] - x[0], points[i, 1] - x[1]
            dist = np.sqrt(dx * dx + dy * dy)
            r[i] = dist - x[2]
            dist = max(dist, tiny)
            J[i, 0], J[i, 1], J[i, 2] = -dx / dist, -dy / dist, -1.0
        return r, J
    e1, e2, n0 = basis[0], basis[1], basis[2]
    raw = n0 + x[3] * e1 + x[4] * e2
    length = np.sqrt(raw @ raw)
    normal = raw / length
    tilt1 = (e1 - (e1 @ normal) * normal) / length  # ∂n/∂t_k applied as d·(I − n nᵀ) e_k / ℓ
    tilt2 = (e2 - (e2 @ normal) * normal) / length
    r = np.empty(2 * n)
    J = np.zeros((2 * n, 6))
    for i in range(n):
        d = points[i] - x[:3]
        h = d @ normal
        rho = np.sqrt(max(d @ d - h * h, 0.0))
        w = root_w[i]
        r[i] = w * h
        r[n + i] = w * (rho - x[5])
        dh1, dh2 = d @ tilt1, d @ tilt2
        inv_rho = 1.0 / rho if rho > 0.0 else 0.0  # a point on the axis gets ρ's gradient 0
        for k in range(3):
            J[i, k] = -w * normal[k]
            J[n + i, k] = -w * (d[k] - h * normal[k]) * inv_rho
        J[i, 3], J[i, 4] = w * dh1, w * dh2
        J[n + i, 3], J[n + i, 4] = -w * h * inv_rho * dh1, -w * h * inv_rho * dh2
        J[n + i, 5] = -w
    return r, J


@njit(cache=True)
def _solve_damped(A, g, scale2, lam):
    """h of (A + λ D²) h = −g by Cholesky (A + λD² is positive definite for λ > 0 and D > 0)."""
    p = A.shape[0]
    M = A.copy()
    for k in range(p):
        M[k, k] += lam * scale2[k]
    L = np.zeros((p, p))
    for i in range(p):
        for j in range(i + 1):
            s = M[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                if s <= 0.0:
                    return np.full(p, np.nan)
                L[i, i] = np.sqrt(s)
            else:
                L[i, j] = s / L[j, j]
    y = np.empty(p)
    for i in range(p):
        s = -g[i]
        for k in range(i):
            s -= L[i, k] * y[k]
        y[i] = s / L[i, i]
    h = np.empty(p)
    for i in range(p - 1, -1, -1):
        s = y[i]
        for k in range(i + 1, p):
            s -= L[k, i] * h[k]
        h[i] = s / L[i, i]
    return h


@njit(cache=True)
def levenberg_marquardt(kind, x0, points, root_w, basis, ftol, xtol, gtol, max_evaluations):
    """Minimise ‖r(x)‖² of residual kind ``kind`` from ``x0`` (module docstring).

    Returns (x, r(x), evaluations).
    """
    x = x0.copy()
    r, J = residuals_jacobian(kind, x, points, root_w, basis)
    evaluations = 1
    cost = r @ r
    p = x.shape[0]
    scale = np.zeros(p)
    lam, nu, radius = -1.0, 2.0, -1.0
    while evaluations < max_evaluations and cost > 0.0:
        A = J.T @ J
        g = J.T @ r
        r_norm = np.sqrt(cost)
        worst = 0.0
        for k in range(p):
            column = np.sqrt(A[k, k])
            scale[k] = max(scale[k], column if column > 0.0 else 1.0)
            if column > 0.0:
                worst = max(worst, abs(g[k]) / (column * r_norm))
        if worst <= gtol:
            break
        scale2 = scale * scale
        if lam < 0.0:
            lam = 1e-3 * np.max(np.diag(A) / scale2)
        accepted, converged = False, False
        while evaluations < max_evaluations:
            h = _solve_damped(A, g, scale2, lam)
            if not np.all(np.isfinite(h)):
                lam, nu = lam * nu, 2.0 * nu
                continue
            step_norm = np.sqrt(np.sum(scale2 * h * h))
            x_norm = np.sqrt(np.sum(scale2 * x * x))
            if radius < 0.0:
                radius = TRUST_FACTOR * (x_norm if x_norm > 0.0 else 1.0)
            if step_norm > radius and np.isfinite(lam * nu):  # beyond the trust radius: damp more, no evaluation
                lam, nu = lam * nu, 2.0 * nu
                continue
            x_new = x + h
            r_new, J_new = residuals_jacobian(kind, x_new, points, root_w, basis)
            evaluations += 1
            cost_new = r_new @ r_new
            predicted = -(2.0 * (g @ h) + h @ (A @ h))  # ‖r‖² − ‖r + J h‖²
            actual = cost - cost_new
            if actual > 0.0 and predicted > 0.0:
                rho = actual / predicted
                x, r, J, cost = x_new, r_new, J_new, cost_new
                lam *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                if rho > 0.75:
                    radius = max(radius, 3.0 * step_norm)
                nu = 2.0
                accepted = True
                converged = (actual <= ftol * (cost + actual) and predicted <= ftol * (cost + actual)) \
                    or step_norm <= xtol * x_norm
                break
            lam, nu = lam * nu, 2.0 * nu
            radius = min(radius, 0.5 * step_norm)
            if step_norm <= xtol * x_norm:
                converged = True
                break
        if converged or not accepted:
            break
    return x, r, evaluations
