"""Temporal models of the motion variable q(t) (SPEC 3, paper Eq. motion_parameter_prop).

Order k keeps the state X = [q, q⁽¹⁾, …, q⁽ᵏ⁾] (dimension k+1); white noise η
drives the (k+1)-th derivative: X_{t+1} = A X_t + B η, η ~ N(0, σ_η²).
Order 0 is a random walk, 1 constant velocity, 2 constant acceleration.
"""

from __future__ import annotations

from math import factorial

import numpy as np
from scipy.ndimage import gaussian_filter1d

from stslam.errors import ConfigError


def _check_order(order: int) -> int:
    if isinstance(order, bool) or not isinstance(order, (int, np.integer)) or order < 0:
        raise ConfigError(f"order: expected an integer ≥ 0, got {order!r}")
    return int(order)


def transition_matrices(order: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Transition matrix A and noise input B of the order-k Taylor model (SPEC 3).

    A[i, j] = δt^(j−i)/(j−i)! for j ≥ i, else 0;  B[i] = δt^(k+1−i)/(k+1−i)!.

    Returns
    -------
    A : numpy.ndarray, shape (k+1, k+1)
    B : numpy.ndarray, shape (k+1,)
    """
    k = _check_order(order)
    if not dt > 0:
        raise ConfigError(f"dt: expected a time step > 0, got {dt!r}")
    A = np.zeros((k + 1, k + 1))
    for i in range(k + 1):
        for j in range(i, k + 1):
            A[i, j] = dt ** (j - i) / factorial(j - i)  # SPEC 3
    B = np.array([dt ** (k + 1 - i) / factorial(k + 1 - i) for i in range(k + 1)])  # SPEC 3
    return A, B


def process_noise(order: int, dt: float, sigma_eta: float) -> np.ndarray:
    """Process noise Q = B Bᵀ σ_η² of the order-k model (SPEC 3), shape (k+1, k+1)."""
    _, B = transition_matrices(order, dt)
    return np.outer(B, B) * sigma_eta**2


def initial_state(q_window, order: int, dt: float, smoothing_sigma: float) -> np.ndarray:
    """Motion state at the last sample of a window (SPEC 3 initialisation).

    q is the motion variable over the window (from inverse kinematics); the d-th
    derivative is Gaussian-smoothed numerical differentiation
    (``gaussian_filter1d(q, σ, order=d)``, which differentiates per sample)
    divided by δt^d. The value itself is the last sample of q.

    Parameters
    ----------
    q_window : array_like, shape (n,)
        Motion variable (m or rad) at n consecutive steps.
    order : int
        Temporal order k.
    dt : float
        Time step δt (s or frames).
    smoothing_sigma : float
        Gaussian width in samples (the paper used 0.6).

    Returns
    -------
    numpy.ndarray, shape (k+1,)
    """
    k = _check_order(order)
    q = np.asarray(q_window, dtype=float).reshape(-1)
    x = np.empty(k + 1)
    x[0] = q[-1]
    for d in range(1, k + 1):
        if q.size <= d or smoothing_sigma <= 0:
            x[d] = 0.0
            continue
        derivative = gaussian_filter1d(q, smoothing_sigma, order=d, mode="nearest")
        x[d] = derivative[-1] / dt**d
    return x
