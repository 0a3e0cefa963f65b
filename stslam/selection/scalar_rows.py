"""The filter bank's rows, compiled, for temporal order 1 and the paper's three models (SPEC 2, 3, 4).

:class:`stslam.selection.bank.FilterBank` steps rows of motion state x = [q, q̇] with
F = [[1, δt], [0, 1]] and the scalar isotropic update (d = 1):

    X⁻ = F X,   P⁻ = F P Fᵀ + Q_j (symmetrised),   q⁻ = X⁻₀
    z_j* = f_j(C_j, q⁻),   j_j = ∂f_j/∂q,   y_j = z − z_j*                 (SPEC 2)
    (whitened by L⁻¹ of the point's own covariance C = L Lᵀ when given: y ← L⁻¹y, j ← L⁻¹j)
    M_j = ρ_j + P⁻₀₀ j·j,   NIS = y·y/ρ − P⁻₀₀ (j·y)²/(ρ M),
    log L = max(−½ (NIS + 2 log ρ + log M + 3 log 2π) [− log det L], MIN_LOG_LIKELIHOOD)
    x = X⁻ + p₀ (j·y)/M,   P = (I − K H) P⁻ (I − K H)ᵀ + (ρ j·j / M²) p₀ p₀ᵀ   (Joseph, symmetrised)

with p₀ the first column of P⁻ and K H = p₀ [j·j/M, 0]. One compiled kernel (numba, cached) steps
every row of a bank, for its step and for its rerun of a window's tail alike, so both give the same
bits. A row's structure is packed as 12 floats (:func:`pack`): static P0; prismatic P0, n̂; revolute
x0, y0, r, v1, v2, P0.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from stslam.articulation.models import PrismaticModel, RevoluteModel, StaticModel
from stslam.kalman.ekf import LOG_2PI, MIN_LOG_LIKELIHOOD

STATIC, PRISMATIC, REVOLUTE = 0, 1, 2
KINDS = {StaticModel: STATIC, PrismaticModel: PRISMATIC, RevoluteModel: REVOLUTE}
PACKED = 12  # floats per packed structure


def pack(kind: int, structure) -> np.ndarray:
    """A structure's numbers for :func:`step_rows` (module docstring), shape (12,)."""
    out = np.zeros(PACKED)
    if kind == STATIC:
        out[:3] = structure.p0
    elif kind == PRISMATIC:
        out[:3], out[3:6] = structure.p0, structure.direction
    else:
        out[:2], out[2] = structure.centre_xy, structure.radius
        out[3:6], out[6:9], out[9:12] = structure.v1, structure.v2, structure.p0
    return out


@njit(cache=True)
def _point(kind, c, q, z_pred, jac):
    """f(C, q) into ``z_pred`` (3,) and ∂f/∂q into ``jac`` (3,) for a packed structure ``c`` (SPEC 2.1–2.3)."""
    if kind == STATIC:  # P0 + l·[1, 1, 1]
        for k in range(3):
            z_pred[k], jac[k] = c[k] + q, 1.0
    elif kind == PRISMATIC:  # P0 + l·n̂
        for k in range(3):
            z_pred[k], jac[k] = c[k] + q * c[3 + k], c[3 + k]
    else:  # (x0 + r cos φ) v1 + (y0 + r sin φ) v2 + P0
        cos, sin = np.cos(q), np.sin(q)
        a, b, r = c[0] + c[2] * cos, c[1] + c[2] * sin, c[2]
        for k in range(3):
            z_pred[k] = a * c[3 + k] + b * c[6 + k] + c[9 + k]
            jac[k] = r * (-sin * c[3 + k] + cos * c[6 + k])


@njit(cache=True)
def _step_row(i, X, P, Q, h, z, kind, c, rr, two_log_rr, L, whiten, log_det_l, X_new, P_new, Y, J, a_out, nis,
              log_lik, z_pred, jac, y, jw):
    """Row ``i`` of :func:`step_rows` into its outputs' row i; returns whether it failed (module docstring)."""
    # P⁻ = F P Fᵀ + Q, symmetrised; X⁻ = F X
    f00, f01 = P[i, 0, 0] + h * P[i, 1, 0], P[i, 0, 1] + h * P[i, 1, 1]
    a00 = f00 + h * f01 + Q[i, 0, 0]
    a01 = f01 + Q[i, 0, 1]
    a10 = P[i, 1, 0] + h * P[i, 1, 1] + Q[i, 1, 0]
    a11 = P[i, 1, 1] + Q[i, 1, 1]
    p00, p01, p11 = a00, 0.5 * (a01 + a10), a11
    xp0, xp1 = X[i, 0] + h * X[i, 1], X[i, 1]
    _point(kind, c, xp0, z_pred, jac)
    for k in range(3):
        y[k] = z[k] - z_pred[k]
        Y[i, k], J[i, k] = y[k], jac[k]
    if whiten:  # y ← L⁻¹ y, j ← L⁻¹ ∂f/∂q: S = a j jᵀ + ρC becomes a j jᵀ + ρI (SPEC 4)
        for k in range(2, -1, -1):
            sy, sj = 0.0, 0.0
            for m in range(k + 1):
                sy += L[k, m] * y[m]
                sj += L[k, m] * jac[m]
            y[k], jw[k] = sy, sj
    else:
        jw[:] = jac
    jj = jw[0] * jw[0] + jw[1] * jw[1] + jw[2] * jw[2]
    jy = jw[0] * y[0] + jw[1] * y[1] + jw[2] * y[2]
    yy = y[0] * y[0] + y[1] * y[1] + y[2] * y[2]
    M = rr + p00 * jj
    a_out[i] = p00
    if not (rr > 0.0 and M > 0.0 and np.isfinite(M)):
        X_new[i, :], P_new[i, :, :], nis[i], log_lik[i] = np.nan, np.nan, np.nan, np.nan
        return True
    v = yy / rr - p00 * jy * jy / (rr * M)
    nis[i] = v
    ll = max(-0.5 * (v + two_log_rr + np.log(M) + 3 * LOG_2PI), MIN_LOG_LIKELIHOOD)
    log_lik[i] = max(ll - log_det_l, MIN_LOG_LIKELIHOOD) if whiten else ll
    X_new[i, 0], X_new[i, 1] = xp0 + p00 * (jy / M), xp1 + p01 * (jy / M)  # K y, K = p₀ jᵀ/M
    i00, i10 = 1.0 - p00 * (jj / M), -p01 * (jj / M)  # I − K H
    b00, b01 = i00 * p00, i00 * p01  # (I − KH) P⁻
    b10, b11 = p01 + i10 * p00, p11 + i10 * p01
    cj = rr * jj / (M * M)  # Joseph form: (I − KH) P⁻ (I − KH)ᵀ + c p₀p₀ᵀ
    n00 = b00 * i00 + cj * (p00 * p00)
    n01 = b01 + b00 * i10 + cj * (p00 * p01)
    n10 = b10 * i00 + cj * (p01 * p00)
    n11 = b11 + b10 * i10 + cj * (p01 * p01)
    P_new[i, 0, 0], P_new[i, 1, 1] = n00, n11
    P_new[i, 0, 1] = P_new[i, 1, 0] = 0.5 * (n01 + n10)
    return False


@njit(cache=True)
def step_rows(X, P, Q, h, z, kinds, packed, rho, two_log_rho, L, whiten, log_det_l):
    """One predict and update of every row (module docstring).

    X (r, 2), P (r, 2, 2), Q (r, 2, 2), δt ``h``, point z (3,), ``kinds`` (r,), ``packed`` (r, 12), ρ and
    2 log ρ (r,); with ``whiten``, L (3, 3) is L⁻¹ of the point's covariance and ``log_det_l`` log det L.
    Returns X (r, 2), P (r, 2, 2), y (r, 3), P⁻₀₀ (r,), ∂f/∂q (r, 3), NIS (r,), log L (r,) and whether each
    row failed (r,) (ρ ≤ 0 or M not positive and finite: its numbers are then NaN).
    """
    r = X.shape[0]
    X_new, P_new = np.empty((r, 2)), np.empty((r, 2, 2))
    Y, J = np.empty((r, 3)), np.empty((r, 3))
    a_out, nis, log_lik = np.empty(r), np.empty(r), np.empty(r)
    failed = np.zeros(r, dtype=np.bool_)
    z_pred, jac, y, jw = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    for i in range(r):
        failed[i] = _step_row(i, X, P, Q, h, z, kinds[i], packed[i], rho[i], two_log_rho[i], L, whiten, log_det_l,
                              X_new, P_new, Y, J, a_out, nis, log_lik, z_pred, jac, y, jw)
    return X_new, P_new, Y, a_out, J, nis, log_lik, failed


@njit(cache=True)
def rerun_rows(X, P, Qs, hs, Z, kinds, packed, rho, two_log_rho, Ls, whiten, log_det_ls):
    """:func:`step_rows` through points Z (m, 3) in turn (δt ``hs`` (m,), Q ``Qs`` (m, r, 2, 2), with ``whiten``
    L⁻¹ ``Ls`` (m, 3, 3) and log det L ``log_det_ls`` (m,) of each point), the same operations step by step;
    stops before the first step where a row fails. Returns X (r, 2), P (r, 2, 2) after the steps taken and
    their number."""
    r = X.shape[0]
    Y, J = np.empty((r, 3)), np.empty((r, 3))
    a_out, nis, log_lik = np.empty(r), np.empty(r), np.empty(r)
    z_pred, jac, y, jw = np.empty(3), np.empty(3), np.empty(3), np.empty(3)
    X_cur, P_cur = X.copy(), P.copy()
    X_new, P_new = np.empty((r, 2)), np.empty((r, 2, 2))
    for k in range(Z.shape[0]):
        failed = False
        for i in range(r):
            if _step_row(i, X_cur, P_cur, Qs[k], hs[k], Z[k], kinds[i], packed[i], rho[i], two_log_rho[i], Ls[k],
                         whiten, log_det_ls[k], X_new, P_new, Y, J, a_out, nis, log_lik, z_pred, jac, y, jw):
                failed = True
        if failed:
            return X_cur, P_cur, k
        X_cur, X_new = X_new, X_cur
        P_cur, P_new = P_new, P_cur
    return X_cur, P_cur, Z.shape[0]
