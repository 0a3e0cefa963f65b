"""The initial motion state of a model filter, from a short window of its motion variable (SPEC 3).

Pure functions used by :class:`stslam.selection.model_filter.ModelFilter` at each (re)fit:
the selection matrix [I, 0, …], the linear map G from a window of q to the
initial state (and its G Gᵀ), the state and covariance themselves, and the
latest evenly spaced run of a window seen in bursts; and the transition and
process noise of a step, shared by every fit.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from stslam.kalman.temporal import MotionModel, initial_state, transition_matrices


def selection_matrix(order: int, dof: int) -> np.ndarray:
    """[I_dof, 0, …, 0], shape (dof, (k+1)·dof): picks q out of the motion state."""
    out = np.zeros((dof, (order + 1) * dof))
    out[:, :dof] = np.eye(dof)
    return out


@lru_cache(maxsize=256)
def derivative_gains(n: int, order: int, dt: float, smoothing_sigma: float) -> np.ndarray:
    """Linear map G (k+1, n) from a window of q to its initial state (SPEC 3).

    :func:`stslam.kalman.temporal.initial_state` is linear in the window (value and
    Gaussian-weighted derivatives at the last sample), so its matrix is found
    column by column from unit windows; the result is cached (read-only). With
    white noise of variance σ_q² on the window, the initial state's covariance
    is σ_q² G Gᵀ.
    """
    G = np.empty((order + 1, n))
    for i in range(n):
        e = np.zeros(n)
        e[i] = 1.0
        G[:, i] = initial_state(e, order, dt, smoothing_sigma)
    G.flags.writeable = False
    return G


@lru_cache(maxsize=256)
def gains_covariance(n: int, order: int, dt: float, smoothing_sigma: float) -> np.ndarray:
    """G Gᵀ (k+1, k+1) of :func:`derivative_gains` (cached, read-only)."""
    G = derivative_gains(n, order, dt, smoothing_sigma)
    out = G @ G.T
    out.flags.writeable = False
    return out


def initial_motion_state(q_window, order: int, dt: float, smoothing_sigma: float,
                         q_sigma) -> tuple[np.ndarray, np.ndarray]:
    """Motion state X and covariance P at the last sample of a window (SPEC 3).

    Parameters
    ----------
    q_window : array_like, shape (n, dof)
        Motion variable over n consecutive steps (by inverse kinematics, SPEC 2).
    order : int
        Temporal order k.
    dt : float
        Time step (s, or 1 frame).
    smoothing_sigma : float
        Gaussian width of the derivative estimate (samples).
    q_sigma : array_like, shape (dof,)
        Standard deviation of each q sample (model unit).

    Returns
    -------
    X : numpy.ndarray, shape ((k+1)·dof,)
        Blocks [q, q⁽¹⁾, …] of ``dof`` entries each.
    P : numpy.ndarray, shape ((k+1)·dof, (k+1)·dof)
        σ_q² G Gᵀ per axis (axes independent): (G Gᵀ) ⊗ diag(σ_q²).
    """
    q = np.asarray(q_window, dtype=float)
    n, dof = q.shape
    G = derivative_gains(n, order, float(dt), float(smoothing_sigma))
    X = G @ q  # (k+1, dof): row d = d-th derivative of every axis
    variance = np.asarray(q_sigma, dtype=float) ** 2
    GGt = gains_covariance(n, order, float(dt), float(smoothing_sigma))
    # (G Gᵀ) ⊗ diag(σ_q²); with one axis the Kronecker product is the same products, element by element
    P = GGt * variance[0] if dof == 1 else np.kron(GGt, np.diag(variance))
    return X.reshape(-1), P


def evenly_spaced_run(dts, first: int, m: int, gap_factor: float = 1.5) -> tuple[int, int]:
    """The latest evenly spaced run of at least two samples in window[first:first + m] (start, length).

    The derivative estimate of SPEC 3 assumes one time step between the
    samples it is given; a track seen in bursts (a landmark out of view for a
    while) breaks that, and over a long gap an angle may even wrap. A sample i
    starts a new run when its gap ``dts[i]`` exceeds ``gap_factor`` × the
    shortest gap in the window. The samples after the chosen run are filtered
    (the Kalman prediction handles any δt). Without such a run the last
    sample alone is returned.

    Parameters
    ----------
    dts : array_like, shape (n,)
        Time from each sample to the previous one (``dts[0]`` unused).
    first, m : int
        The candidate window, samples ``first … first + m − 1``.
    """
    if m <= 1:
        return first, m
    gaps = dts[first + 1:first + m]
    gaps = gaps.tolist() if isinstance(gaps, np.ndarray) else [float(g) for g in gaps]
    limit = gap_factor * min(gaps)
    breaks = [first + 1 + i for i, g in enumerate(gaps) if g > limit]  # samples that start a run
    starts = [first] + breaks
    ends = breaks + [first + m]
    for start, end in zip(starts[::-1], ends[::-1], strict=True):
        if end - start >= 2:
            return int(start), int(end - start)
    return first + m - 1, 1


@lru_cache(maxsize=64)
def _one_axis_terms(order: int, dt: float) -> tuple[np.ndarray, np.ndarray]:
    A, B = transition_matrices(order, dt)
    BBt = np.outer(B, B)
    A.flags.writeable = False
    BBt.flags.writeable = False
    return A, BBt


def step_matrices(order: int, dof: int, dt: float, sigma_eta: float) -> tuple[np.ndarray, np.ndarray]:
    """F and Q of :meth:`stslam.kalman.temporal.MotionModel.matrices` (Taylor noise) over a step δt.

    Every refit has its own σ_η (in q's unit), so a cache per model would
    recompute A and B Bᵀ at each fit; here they are kept per δt, and with one
    axis the Kronecker products with I₁ are the same numbers: F = A, Q = σ_η² B Bᵀ (SPEC 3).
    """
    if dof != 1:
        return MotionModel(order, dof, sigma_eta).matrices(dt)
    A, BBt = _one_axis_terms(order, float(dt))
    return A, BBt * sigma_eta ** 2
