"""The one (extended) Kalman filter core every filter in stslam uses.

Symbols follow the textbook (and filterpy): state ``x`` (n,), covariance ``P``
(n, n), transition Jacobian ``F``, process noise ``Q``, measurement Jacobian
``H`` (m, n), measurement noise ``R`` (m, m), innovation ``y``, its covariance
``S`` and gain ``K``. Functions are pure: arrays in, new arrays out.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve, get_lapack_funcs

from stslam.errors import StslamError
from stslam.kalman.symmetry import symmetrise, symmetrised  # noqa: F401 (symmetrise: part of this module's API)

LOG_2PI = float(np.log(2.0 * np.pi))
# Smallest log-likelihood kept, so that model probabilities never collapse to
# exactly zero (filterpy keeps likelihoods above the smallest float likewise).
MIN_LOG_LIKELIHOOD = float(np.log(np.finfo(float).tiny))
# LAPACK's Cholesky factorisation and solve for float64, the routines scipy.linalg's
# cho_factor / cho_solve call; called directly they skip those wrappers' per-call checks,
# which cost more than the factorisation of the small S of a filter step.
_POTRF, _POTRS = get_lapack_funcs(("potrf", "potrs"), (np.empty((1, 1)),))


class InnovationCovarianceError(StslamError):
    """The innovation covariance S is not positive definite."""


@dataclass(frozen=True)
class Update:
    """Result of one measurement update.

    Attributes
    ----------
    x, P : numpy.ndarray
        Posterior state (n,) and covariance (n, n).
    y : numpy.ndarray
        Innovation z − h(x⁻), shape (m,).
    S : numpy.ndarray
        Innovation covariance H P⁻ Hᵀ + R, shape (m, m).
    log_likelihood : float
        log N(y; 0, S), floored at ``MIN_LOG_LIKELIHOOD``.
    nis : float
        Normalised innovation squared yᵀ S⁻¹ y (χ² with m degrees of freedom).
    accepted : bool
        False when an innovation gate rejected the measurement (x, P unchanged).
    """

    x: np.ndarray
    P: np.ndarray
    y: np.ndarray
    S: np.ndarray
    log_likelihood: float
    nis: float
    accepted: bool = True


def predict(x, P, F, Q, fx=None):
    """Prediction step.

    x⁻ = F x (or ``fx`` when the motion is nonlinear and F is its Jacobian);
    P⁻ = F P Fᵀ + Q, symmetrised.
    """
    x_pred = np.asarray(fx, dtype=float) if fx is not None else F @ x
    P_pred = F @ P @ F.T + Q  # P = FPF' + Q
    return x_pred, 0.5 * (P_pred + P_pred.T)


def cholesky_factor(S):
    """The lower Cholesky factor of S as ``scipy.linalg.cho_factor(S, lower=True)`` returns it.

    For a finite float64 matrix it calls LAPACK ``potrf`` directly (the same
    routine and arguments, so the same numbers); anything else goes through
    scipy. Raises LinAlgError (not positive definite) or ValueError (not finite).
    """
    if not (isinstance(S, np.ndarray) and S.dtype == np.float64 and S.ndim == 2 and S.size
            and S.shape[0] == S.shape[1]):
        return cho_factor(S, lower=True, check_finite=True)
    if not np.isfinite(S).all():
        raise ValueError("array must not contain infs or NaNs")
    c, info = _POTRF(S, lower=True, overwrite_a=False, clean=False)
    if info > 0:
        raise LinAlgError(f"{info}-th leading minor of the array is not positive definite")
    if info < 0:
        raise ValueError(f"LAPACK reported an illegal value in {-info}-th argument on entry to POTRF")
    return c, True


def cholesky_solve(factor, b):
    """S⁻¹ b from :func:`cholesky_factor`'s result, as ``scipy.linalg.cho_solve(factor, b)`` gives it."""
    c, lower = factor
    if not (isinstance(b, np.ndarray) and b.dtype == np.float64 and b.size and c.dtype == np.float64
            and b.shape[0] == c.shape[0]):
        return cho_solve(factor, b)
    if not np.isfinite(b).all():
        raise ValueError("array must not contain infs or NaNs")
    x, info = _POTRS(c, b, lower=lower, overwrite_b=False)
    if info != 0:
        raise ValueError(f"illegal value in {-info}th argument of internal potrs")
    return x


def innovation_stats(y, S):
    """NIS yᵀS⁻¹y and log N(y; 0, S) for innovation ``y`` (m,) with covariance ``S`` (m, m)."""
    try:
        factor = cholesky_factor(S)
    except (LinAlgError, ValueError) as error:
        raise InnovationCovarianceError(f"innovation covariance is not positive definite: {S!r}") from error
    nis = float(y @ cholesky_solve(factor, y))
    log_det = 2.0 * float(np.sum(np.log(np.diag(factor[0]))))
    log_likelihood = -0.5 * (nis + log_det + y.size * LOG_2PI)
    return nis, max(log_likelihood, MIN_LOG_LIKELIHOOD), factor


def update(x, P, y, H, R) -> Update:
    """Measurement update with innovation ``y`` = z − h(x⁻) (already wrapped if angular).

    S = H P Hᵀ + R;  K = P Hᵀ S⁻¹;  x = x + K y;
    P = (I − K H) P (I − K H)ᵀ + K R Kᵀ — the Joseph form, which keeps P
    symmetric positive semi-definite even when K is not the optimal gain
    (e.g. after round-off over thousands of steps).
    """
    y = np.asarray(y, dtype=float).reshape(-1)
    H = np.atleast_2d(np.asarray(H, dtype=float))
    R = np.atleast_2d(np.asarray(R, dtype=float))
    PHt = P @ H.T
    S = H @ PHt + R  # S = HPH' + R
    S = 0.5 * (S + S.T)
    nis, log_likelihood, factor = innovation_stats(y, S)
    K = cholesky_solve(factor, PHt.T).T  # K = PH'S^-1
    x_new = x + K @ y
    I_KH = np.eye(P.shape[0]) - K @ H
    P_new = I_KH @ P @ I_KH.T + K @ R @ K.T  # Joseph form
    return Update(x_new, 0.5 * (P_new + P_new.T), y, S, log_likelihood, nis)


def augment(x, P, x_new, P_new, P_cross=None):
    """Append a block to the state: returns [x; x_new] and the bordered covariance.

    ``P_cross`` (n, k) is the covariance between the old state and the new block
    (zero when omitted).
    """
    x_new = np.asarray(x_new, dtype=float).reshape(-1)
    n, k = x.size, x_new.size
    P_out = np.zeros((n + k, n + k))
    P_out[:n, :n] = P
    P_out[n:, n:] = P_new
    if P_cross is not None:
        P_out[:n, n:] = P_cross
        P_out[n:, :n] = P_cross.T
    return np.concatenate([x, x_new]), P_out


def marginalise_range(x, P, start: int, end: int) -> tuple[np.ndarray, np.ndarray]:
    """x and P with entries start..end−1 (a block's range) marginalised out: new arrays, by four slices."""
    n = x.size
    if not 0 <= start <= end <= n or P.shape != (n, n):
        raise ValueError(f"marginalise_range: entries {start}..{end} of a state of size {n} (P {P.shape})")
    P_out = np.empty((n - (end - start),) * 2)
    P_out[:start, :start] = P[:start, :start]
    P_out[:start, start:] = P[:start, end:]
    P_out[start:, :start] = P[end:, :start]
    P_out[start:, start:] = P[end:, end:]
    return np.concatenate([x[:start], x[end:]]), P_out


def predict_blocks(x, P, blocks, spans=None):
    """Prediction step with a block-diagonal transition (identity outside the blocks).

    The same equations as :func:`predict`, x⁻ = F x (or the nonlinear f(x)) and
    P⁻ = F P Fᵀ + Q, evaluated block by block: with F = blockdiag(F_i) and
    identity elsewhere, (F P Fᵀ)_ij = F_i P_ij F_jᵀ, so rows of block i are
    multiplied by F_i, then columns by F_iᵀ — O(n²) per step instead of O(n³).

    Parameters
    ----------
    x : numpy.ndarray, shape (n,)
    P : numpy.ndarray, shape (n, n)
    blocks : sequence of (index, F_i, Q_i, fx_i)
        ``index``: integer state indices, shape (k,) for one block or (b, k)
        for b blocks sharing the same F_i and Q_i (all blocks disjoint);
        ``F_i`` (k, k) transition Jacobian or None for identity; ``Q_i`` (k, k)
        process noise or None; ``fx_i`` predicted mean (shape of ``index``) or
        None for F_i x_i.
    spans : sequence of (slice or None), optional
        Per block, :func:`block_span` of its ``index``, for a caller that keeps
        its blocks from step to step (found here when not given).

    Returns
    -------
    x_pred, P_pred : numpy.ndarray
        New arrays; P_pred symmetrised.
    """
    x_pred = np.array(x, dtype=float)
    P_pred = np.array(P, dtype=float)
    n = P_pred.shape[0]
    if spans is None:  # consecutive indices: views, not gathered copies
        spans = [block_span(index) for index, _, _, _ in blocks]
    for (index, F_i, _, fx_i), span in zip(blocks, spans):
        if fx_i is not None:
            x_pred[index] = fx_i
        elif F_i is not None:
            x_pred[index] = x_pred[index] @ F_i.T
        if F_i is not None and span is not None:
            rows = P_pred[span].reshape(np.shape(index) + (n,))
            rows[...] = np.matmul(F_i, rows)  # rows: F P
        elif F_i is not None:
            P_pred[index, :] = np.matmul(F_i, P_pred[index, :])
    for (index, F_i, Q_i, _), span in zip(blocks, spans):
        if F_i is not None and span is not None:
            columns = P_pred[:, span].reshape((n,) + np.shape(index))
            columns[...] = _times_transpose(columns, F_i)  # columns: (F P) F'
        elif F_i is not None:
            P_pred[:, index] = _times_transpose(P_pred[:, index], F_i)
        if Q_i is not None:
            index_2d = np.atleast_2d(index)
            P_pred[index_2d[:, :, None], index_2d[:, None, :]] += 0.5 * (Q_i + Q_i.T)  # + Q
    # Only the rows and columns of blocks with an F changed (Q is added symmetrically):
    # symmetrise just those, O(n·k) instead of O(n²).
    for (index, F_i, _, _), span in zip(blocks, spans):
        if F_i is not None:
            flat = np.ravel(index) if span is None else span
            mean = 0.5 * (P_pred[flat, :] + P_pred[:, flat].T)
            P_pred[flat, :] = mean
            P_pred[:, flat] = mean.T
    return x_pred, P_pred


def block_span(index) -> slice | None:
    """``index`` (k,) or (b, k) as a slice when its entries are consecutive and in order, else None."""
    flat = np.ravel(index)
    start = int(flat[0])
    if int(flat[-1]) - start + 1 == flat.size and np.array_equal(flat, np.arange(start, start + flat.size)):
        return slice(start, start + flat.size)
    return None


def _times_transpose(columns, F):
    """``columns @ F.T`` for columns (n, k) or (n, b, k) of b blocks sharing F (k, k): b ≥ 2 as one (n·b, k) × (k, k)
    product (equal to the stacked ones to the last bit for b = 2..24; b = 1 rounds differently: stacked)."""
    if columns.ndim == 2 or columns.shape[1] == 1:
        return columns @ F.T
    return (columns.reshape(-1, F.shape[1]) @ F.T).reshape(columns.shape)


def innovation_covariance_sparse(P, cols, H_cols, R):
    """S = H P Hᵀ + R for an H that is zero outside the state columns ``cols``; also P Hᵀ.

    Returns
    -------
    S : numpy.ndarray, shape (m, m)
        Symmetrised innovation covariance.
    PHt : numpy.ndarray, shape (n, m)
    """
    S, PHt, _, _ = _innovation_covariance_sparse(P, cols, H_cols, R)
    return S, PHt


def _innovation_covariance_sparse(P, cols, H_cols, R):
    """S and PHᵀ as :func:`innovation_covariance_sparse`, with P[:, cols] and PHᵀ[cols] for reuse."""
    P_cols = P[:, cols]
    PHt = P_cols @ H_cols.T
    PHt_cols = PHt[cols]
    S = H_cols @ PHt_cols + R  # S = HPH' + R
    return 0.5 * (S + S.T), PHt, P_cols, PHt_cols


def innovation_covariances_sparse(P, cols, H_cols, R) -> list:
    """Sᵢ = Hᵢ P Hᵢᵀ + Rᵢ (m, m) of k measurements each taken on its own (as :func:`nis_sparse` forms
    them, not symmetrised), each Hᵢ zero outside its state columns ``cols[i]``; ``R`` (m, m) for all or
    (k, m, m). One stacked product per number of columns instead of one per measurement."""
    out = [None] * len(cols)
    for group, S in _stacked_innovation_covariances(P, cols, H_cols, R):
        for row, j in enumerate(group.tolist()):
            out[j] = S[row]
    return out


def _stacked_innovation_covariances(P, cols, H_cols, R):
    """(measurement indices (g,), their S = H P Hᵀ + R (g, m, m)) per group of measurements with the same
    number of state columns."""
    R = np.asarray(R, dtype=float)
    sizes = np.array([np.size(c) for c in cols])
    for size in np.unique(sizes):
        group = np.flatnonzero(sizes == size)
        C = np.stack([cols[j] for j in group])  # (g, c) state columns
        H = np.stack([H_cols[j] for j in group])  # (g, m, c)
        S = H @ P[C[:, :, None], C[:, None, :]] @ H.transpose(0, 2, 1)
        S = S + (R if R.ndim == 2 else R[group])  # S = HPH' + R
        yield group, S


def nis_sparse(P, y, cols, H_cols, R) -> np.ndarray:
    """NIS yᵢᵀSᵢ⁻¹yᵢ (k,) of k measurements each taken on its own, each H zero outside its columns.

    Sᵢ = Hᵢ P Hᵢᵀ + Rᵢ is measurement i's marginal innovation covariance, the
    same as :func:`innovation_covariance_sparse` gives, and the NIS the same as
    :func:`innovation_stats` gives; measurements with the same number of
    columns are done together (one stacked product and solve per size).

    Parameters
    ----------
    P : numpy.ndarray, shape (n, n)
    y : array_like, shape (k, m)
        Innovations z − h(x⁻), one row per measurement.
    cols : sequence of k integer arrays, shape (cᵢ,)
        State indices where each measurement's H is non-zero.
    H_cols : sequence of k arrays, shape (m, cᵢ)
        Those columns of each H.
    R : array_like, shape (m, m) for all or (k, m, m)

    Raises
    ------
    InnovationCovarianceError
        Some Sᵢ is not finite and positive definite.
    """
    nis = np.empty(len(cols))
    if nis.size == 0:
        return nis
    y = np.asarray(y, dtype=float).reshape(len(cols), -1)
    for group, S in _stacked_innovation_covariances(P, cols, H_cols, R):
        S = 0.5 * (S + S.transpose(0, 2, 1))
        try:
            if not np.all(np.isfinite(S)):
                raise np.linalg.LinAlgError("non-finite entries")
            np.linalg.cholesky(S)  # positive definite, as innovation_stats requires
        except np.linalg.LinAlgError as error:
            raise InnovationCovarianceError(f"innovation covariance is not positive definite: {error}") from error
        y_g = y[group]
        nis[group] = np.einsum("gi,gi->g", y_g, np.linalg.solve(S, y_g[:, :, None])[:, :, 0])  # y'S^-1y
    return nis


def update_sparse(x, P, y, cols, H_cols, R, max_nis: float | None = None, frozen=None) -> Update:
    """Measurement update whose Jacobian H is zero outside the state columns ``cols``.

    The same update as :func:`update` (Joseph form), computed in O(n² m) instead
    of O(n³) by skipping H's zero columns: with PHᵀ = P[:, cols] H_colsᵀ,
    S = H_cols PHᵀ[cols] + R, K = PHᵀ S⁻¹ and A = I − K H,
    A P = P − K (PHᵀ)ᵀ, A P Aᵀ = A P − ((A P)[:, cols] H_colsᵀ) Kᵀ, so
    P = A P Aᵀ + K R Kᵀ = P − K (PHᵀ)ᵀ − ((A P)[:, cols] H_colsᵀ − K R) Kᵀ:
    the Joseph form expanded exactly (valid for any gain), evaluated with one
    n × 2m × n product.

    Parameters
    ----------
    x, P : numpy.ndarray, shapes (n,), (n, n)
    y : array_like, shape (m,)
        Innovation z − h(x⁻).
    cols : array_like of int, shape (c,)
        State indices where H is non-zero.
    H_cols : array_like, shape (m, c)
        Those columns of H.
    R : array_like, shape (m, m)
    max_nis : float, optional
        Innovation gate: when yᵀS⁻¹y exceeds it the measurement is rejected
        and the returned Update has ``accepted=False`` and the prior x, P.
    frozen : array_like of int, optional
        State indices held as consider parameters (the Schmidt–Kalman filter; Simon 2006, §7.5):
        their rows of K are zero, so they keep their mean and covariance, while their
        covariance and cross-covariances enter S and the other states' gains, and the
        cross-covariances are updated (the Joseph form above holds for any gain).
    """
    y = np.asarray(y, dtype=float).reshape(-1)
    cols = np.asarray(cols, dtype=int)
    H_cols = np.atleast_2d(np.asarray(H_cols, dtype=float))
    R = np.atleast_2d(np.asarray(R, dtype=float))
    S, PHt, P_cols, PHt_cols = _innovation_covariance_sparse(P, cols, H_cols, R)
    nis, log_likelihood, factor = innovation_stats(y, S)
    if max_nis is not None and nis > max_nis:
        return Update(x, P, y, S, log_likelihood, nis, accepted=False)
    K = cholesky_solve(factor, PHt.T).T  # K = PH'S^-1
    if frozen is not None and len(frozen):
        K[frozen] = 0.0  # consider parameters are not updated (Schmidt–Kalman)
    x_new = x + K @ y
    # A P = P − K (PH')';  its columns ``cols`` cost O(n c m):
    AP_cols = P_cols - K @ PHt_cols.T
    # Joseph form A P A' + K R K' = P − K (PH')' − (AP H' − K R) K', as one rank-2m product.
    M = AP_cols @ H_cols.T - K @ R
    P_new = np.concatenate((K, M), axis=1) @ np.concatenate((PHt, K), axis=1).T
    np.subtract(P, P_new, out=P_new)
    return Update(x_new, symmetrised(P_new), y, S, log_likelihood, nis)
