"""The Kalman update for a 3D point measurement with isotropic noise, in the state's own small dimension.

For a model with ``d`` motion variables seen as a 3D point, H = [J, 0, …, 0]
with J = ∂f/∂q (3, d), and R = ρ·I₃ (the structure inflation of
:mod:`stslam.selection.model_filter`). Then, with A = P_qq (d, d) the
covariance of q, the push-through identity gives S⁻¹ and det S from a d × d
system instead of a 3 × 3 Cholesky factor:

    S = J A Jᵀ + ρ I₃
    S⁻¹ = (I₃ − J (ρ I_d + A JᵀJ)⁻¹ A Jᵀ) / ρ
    det S = ρ^(3−d) · det(ρ I_d + A JᵀJ)

(Sylvester's determinant identity). The result equals
:func:`stslam.kalman.ekf.update` up to round-off (same Joseph-form P), at a
fraction of its cost for d = 1, the case of every model in the paper.
"""

from __future__ import annotations

import numpy as np

from stslam.kalman.ekf import LOG_2PI, MIN_LOG_LIKELIHOOD, InnovationCovarianceError, Update


def isotropic_update(x, P, y, J, rho: float) -> Update:
    """Update of state ``x`` (n,), ``P`` (n, n) whose first d entries are q, with innovation ``y`` (3,).

    ``J`` (3, d) = ∂f/∂q at the prediction, ``rho`` > 0 the measurement variance per coordinate.
    Raises :class:`~stslam.kalman.ekf.InnovationCovarianceError` when S is not positive definite.
    """
    d = J.shape[1]
    if d == 1:
        return _update_one(x, P, y, J[:, 0], rho)
    A = P[:d, :d]
    JtJ = J.T @ J
    M = rho * np.eye(d) + A @ JtJ  # ρ I_d + A JᵀJ
    det_M = float(np.linalg.det(M)) if d > 1 else float(M[0, 0])
    if not (rho > 0.0 and det_M > 0.0 and np.isfinite(det_M)):
        raise InnovationCovarianceError(f"innovation covariance is not positive definite (ρ = {rho!r}, "
                                        f"det(ρI + A JᵀJ) = {det_M!r})")
    Jty = J.T @ y
    w = np.linalg.solve(M, A @ Jty) if d > 1 else (A @ Jty) / det_M
    s_inv_y = (y - J @ w) / rho  # S⁻¹ y
    nis = float(y @ s_inv_y)
    log_det = (3 - d) * np.log(rho) + np.log(det_M)
    log_likelihood = max(-0.5 * (nis + log_det + 3 * LOG_2PI), MIN_LOG_LIKELIHOOD)
    PHt = P[:, :d] @ J.T  # P Hᵀ (n, 3)
    # K = P Hᵀ S⁻¹, with S⁻¹ applied to each row of P Hᵀ
    W = np.linalg.solve(M, A @ (J.T @ PHt.T)) if d > 1 else (A @ (J.T @ PHt.T)) / det_M
    K = ((PHt.T - J @ W) / rho).T
    x_new = x + K @ y
    KH = np.zeros_like(P)
    KH[:, :d] = K @ J
    I_KH = np.eye(P.shape[0]) - KH
    P_new = I_KH @ P @ I_KH.T + rho * (K @ K.T)  # Joseph form
    S = J @ A @ J.T + rho * np.eye(3)
    return Update(x_new, 0.5 * (P_new + P_new.T), y, S, log_likelihood, nis)


def _update_one(x, P, y, j, rho: float) -> Update:
    """:func:`isotropic_update` for d = 1: J = j (3,), A = P₀₀, M = ρ + A·|j|², S⁻¹ j = j/M."""
    a = float(P[0, 0])
    jj = float(j @ j)
    jy = float(j @ y)
    M = rho + a * jj
    if not (rho > 0.0 and M > 0.0 and np.isfinite(M)):
        raise InnovationCovarianceError(f"innovation covariance is not positive definite (ρ = {rho!r}, M = {M!r})")
    nis = float(y @ y) / rho - a * jy * jy / (rho * M)
    log_likelihood = max(-0.5 * (nis + 2.0 * np.log(rho) + np.log(M) + 3 * LOG_2PI), MIN_LOG_LIKELIHOOD)
    p0 = P[:, 0]
    x_new = x + p0 * (jy / M)  # K y, K = p0 jᵀ/M
    k = p0 * (jj / M)  # K J: the only non-zero column of K H
    I_KH = np.eye(P.shape[0])
    I_KH[:, 0] -= k
    P_new = I_KH @ P @ I_KH.T + (rho * jj / (M * M)) * np.outer(p0, p0)  # Joseph form
    S = a * np.outer(j, j) + rho * np.eye(3)
    return Update(x_new, 0.5 * (P_new + P_new.T), y, S, log_likelihood, nis)
