"""Kalman filter of a directly observed motion variable under the order-k model (SPEC 3, 8.2).

The state is X = [q, q⁽¹⁾, …, q⁽ᵏ⁾] (SPEC 3); the observation is q itself plus
white noise, z_t = H X_t + ν, H = [1, 0, …, 0], ν ~ N(0, R). Symbols, as in
:mod:`stslam.kalman.ekf` which does every predict and update: x, P (state and its
covariance, units of q per s^d), F = A (transition), Q (process noise), H, R;
F and Q come from :class:`stslam.kalman.temporal.MotionModel`.

:func:`filter_trace` runs a whole trace (pure: arrays in, arrays out).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stslam.kalman import ekf
from stslam.kalman.temporal import PROCESS_NOISE_MODELS, MotionModel

__all__ = ["PROCESS_NOISE_MODELS", "TraceFilterResult", "filter_trace", "observation_matrix"]


def observation_matrix(order: int) -> np.ndarray:
    """H = [1, 0, …, 0], shape (1, k+1): the filter observes q itself (SPEC 8.2)."""
    H = np.zeros((1, order + 1))
    H[0, 0] = 1.0
    return H


@dataclass(frozen=True)
class TraceFilterResult:
    """What :func:`filter_trace` returns; index t is the t-th sample of the trace.

    Rows before ``start`` (the last sample of the initialisation window) are NaN.

    Attributes
    ----------
    states : numpy.ndarray, shape (n, k+1)
        Filtered state x_{t|t} (row ``start`` holds the initial state).
    variances : numpy.ndarray, shape (n, k+1)
        Diagonal of P_{t|t}.
    predicted : numpy.ndarray, shape (n, K)
        predicted[t, h−1] = q predicted for time t from x_{t−h|t−h}, h = 1 … K
        (column 0 is the one-step prediction whose residual is the innovation).
    log_likelihood : numpy.ndarray, shape (n,)
        log N(y_t; 0, S_t) of each innovation, t > start.
    nis : numpy.ndarray, shape (n,)
        Normalised innovation squared y_t² / S_t, t > start.
    start : int
        Index of the initial state.
    """

    states: np.ndarray
    variances: np.ndarray
    predicted: np.ndarray
    log_likelihood: np.ndarray
    nis: np.ndarray
    start: int


def filter_trace(times, z, x0, P0, start: int, sigma_eta: float, R: float, *,
                 noise_model: str = "taylor", horizon: int = 1) -> TraceFilterResult:
    """Filter a trace of q from the initial state at sample ``start`` (SPEC 3, 8.2).

    For t = start+1 … n−1: predict with F = A(δt_t), Q(δt_t) over the actual
    step δt_t = t_t − t_{t−1} (uniform sampling needs no special case), then
    update with z_t. After each update (and at ``start``) the state is
    propagated h = 1 … K steps ahead along the sample times, noise-free mean
    x_{t+h|t} = A(t_{t+h} − t_t) x_{t|t}, to score predictions.

    Parameters
    ----------
    times : array_like, shape (n,)
        Strictly increasing sample times (s).
    z : array_like, shape (n,)
        Observations of q (units of q, e.g. rad).
    x0, P0 : array_like
        State (k+1,) and covariance (k+1, k+1) at sample ``start``.
    start : int
        Index of the sample the initial state belongs to (window end).
    sigma_eta : float
        Process-noise standard deviation (see :func:`stslam.kalman.temporal.noise_matrix`).
    R : float
        Observation-noise variance.
    noise_model : str
        ``"taylor"`` or ``"identity"``.
    horizon : int
        K, the longest prediction horizon scored (samples), ≥ 1.
    """
    t = np.asarray(times, dtype=float).reshape(-1)
    z = np.asarray(z, dtype=float).reshape(-1)
    x = np.asarray(x0, dtype=float).reshape(-1)
    P = np.asarray(P0, dtype=float)
    n, k, K = z.size, x.size - 1, int(horizon)
    if t.shape != z.shape:
        raise ValueError(f"times and z must have the same shape, got {t.shape} and {z.shape}")
    if P.shape != (k + 1, k + 1):
        raise ValueError(f"P0 must have shape {(k + 1, k + 1)} for a state of size {k + 1}, got {P.shape}")
    if not 0 <= start < n or K < 1:
        raise ValueError(f"need 0 ≤ start < {n} and horizon ≥ 1, got start={start}, horizon={horizon}")
    H = observation_matrix(k)
    R_mat = np.array([[float(R)]])
    states = np.full((n, k + 1), np.nan)
    variances = np.full((n, k + 1), np.nan)
    predicted = np.full((n, K), np.nan)
    log_likelihood = np.full(n, np.nan)
    nis = np.full(n, np.nan)
    steps = np.diff(t)
    motion = MotionModel(k, 1, sigma_eta, noise_model)  # F = A, Q per step (SPEC 3)

    def store(i, x, P):
        states[i], variances[i] = x, np.diag(P)
        for h in range(1, min(K, n - 1 - i) + 1):
            A_h = motion.matrices(t[i + h] - t[i])[0]
            predicted[i + h, h - 1] = (A_h @ x)[0]  # q_{t+h|t} = [A(Δ) x_{t|t}]₀

    store(start, x, P)
    for i in range(start + 1, n):
        F, Q = motion.matrices(steps[i - 1])
        x, P = ekf.predict(x, P, F, Q)  # x = Fx;  P = FPF' + Q
        result = ekf.update(x, P, z[i:i + 1] - H @ x, H, R_mat)  # y = z − Hx
        x, P = result.x, result.P
        log_likelihood[i], nis[i] = result.log_likelihood, result.nis
        store(i, x, P)
    return TraceFilterResult(states, variances, predicted, log_likelihood, nis, start)
