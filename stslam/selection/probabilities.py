"""Model-probability arithmetic of online selection, in log space (SPEC 4, paper Algorithm 1).

Pure functions on log μ (r,) and per-model log-likelihoods (r,):
:func:`threshold_update` (Algorithm 1's Bayes step), :func:`imm_update` (the
switching-probability IMM: Markov prediction with Π, rows = from, then Bayes),
and :func:`first_argmax_mismatch` for the step where plain arg-max selection
would first have been wrong. Conventions are those of :mod:`stslam.selection.selector`.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# Floor of a log probability: the smallest normal float, so a model far off never reaches
# exactly 0 and can come back (log μ = −inf is kept for a model that cannot be fitted).
MIN_LOG_MU = float(np.log(np.finfo(float).tiny))


def logsumexp(a, axis=None):
    """log Σ exp(a) along ``axis``, computed stably around the maximum (−inf entries allowed)."""
    a = np.asarray(a, dtype=float)
    peak = np.max(a, axis=axis, keepdims=True)
    peak = np.where(np.isfinite(peak), peak, 0.0)
    with np.errstate(divide="ignore"):
        out = np.log(np.sum(np.exp(a - peak), axis=axis, keepdims=True)) + peak
    return out.item() if axis is None else np.squeeze(out, axis=axis)


def normalise_log(log_w) -> np.ndarray:
    """log(w / Σ w) for log-weights (r,), −inf entries (μ = 0) kept; floored at ``MIN_LOG_MU``.

    Raises ValueError when every weight is zero (no model applicable).
    """
    log_w = np.asarray(log_w, dtype=float)
    alive = np.isfinite(log_w)
    if alive.all() and log_w.ndim == 1:  # no mask needed: logsumexp's operations on the whole vector
        peak = np.max(log_w, keepdims=True)
        out = log_w - (np.log(np.sum(np.exp(log_w - peak), keepdims=True)) + peak).item()
        return np.maximum(out, MIN_LOG_MU)
    if not alive.any():
        raise ValueError("no model has a non-zero probability")
    out = np.full(log_w.shape, -np.inf)
    out[alive] = log_w[alive] - logsumexp(log_w[alive])
    out[alive] = np.maximum(out[alive], MIN_LOG_MU)
    return out


def threshold_update(log_mu, log_likelihood) -> np.ndarray:
    """μ_j(t) ∝ L_j μ_j(t−1) in log space (SPEC 4, paper Eq. choose_motion), shape (r,)."""
    log_w = np.asarray(log_mu, dtype=float) + np.asarray(log_likelihood, dtype=float)
    return _normalise_finite(log_w) if np.isfinite(log_w).all() else normalise_log(log_w)


def markov_matrix(n_models: int, stay_probability: float) -> np.ndarray:
    """Π with ``stay_probability`` on the diagonal, the rest spread evenly (rows = from)."""
    if n_models == 1:
        return np.ones((1, 1))
    Pi = np.full((n_models, n_models), (1.0 - stay_probability) / (n_models - 1))
    np.fill_diagonal(Pi, stay_probability)
    return Pi


def imm_prior(log_mu, transition) -> np.ndarray:
    """Predicted log μ⁻_j = log Σ_i μ_i Π_ij (rows of Π = from), shape (r,).

    A model with log μ_i = −inf contributes nothing; transitions *into* a model
    that is not applicable (log μ_j = −inf is kept −inf) are dropped and the
    result renormalised.
    """
    log_mu = np.asarray(log_mu, dtype=float)
    with np.errstate(divide="ignore"):
        log_Pi = np.log(np.asarray(transition, dtype=float))
    log_prior = logsumexp(log_mu[:, None] + log_Pi, axis=0)  # Σ_i μ_i Π_ij
    log_prior[~np.isfinite(log_mu)] = -np.inf
    return normalise_log(log_prior)


def imm_update(log_mu, log_likelihood, transition, log_transition=None) -> np.ndarray:
    """One switching-probability IMM step: Markov prediction then Bayes (module docstring).

    ``log_transition`` (optional) is log Π, computed once by the caller.
    """
    log_mu = np.asarray(log_mu, dtype=float)
    log_likelihood = np.asarray(log_likelihood, dtype=float)
    if log_transition is not None:
        out = _imm_finite(log_mu, log_likelihood, np.asarray(log_transition, dtype=float), MIN_LOG_MU)
        if out is not None:
            return out
    return threshold_update(imm_prior(log_mu, transition), log_likelihood)


@njit(cache=True)
def _imm_finite(log_mu, log_likelihood, log_transition, floor):
    """:func:`imm_update` when every term is finite (else None), compiled: the operations of :func:`imm_prior`
    and :func:`normalise_log` without their masks (log Σ_i exp(log μ_i + log Π_ij), normalised, floored)."""
    r = log_mu.size
    for i in range(r):
        if not (np.isfinite(log_mu[i]) and np.isfinite(log_likelihood[i])):
            return None
    prior = np.empty(r)
    for j in range(r):
        peak = -np.inf
        for i in range(r):
            peak = max(peak, log_mu[i] + log_transition[i, j])
        total = 0.0
        for i in range(r):
            total += np.exp(log_mu[i] + log_transition[i, j] - peak)
        prior[j] = np.log(total) + peak
    prior = _normalised(prior, floor)
    return _normalised(prior + log_likelihood, floor)


@njit(cache=True)
def _normalised(log_w, floor):
    """:func:`_normalise_finite` compiled: log_w − log Σ exp(log_w), floored at ``floor``."""
    peak = np.max(log_w)
    total = 0.0
    for j in range(log_w.size):
        total += np.exp(log_w[j] - peak)
    return np.maximum(log_w - (np.log(total) + peak), floor)


def _normalise_finite(log_w: np.ndarray) -> np.ndarray:
    """:func:`normalise_log` of finite log-weights: the same operations without the masks."""
    peak = log_w.max()
    out = log_w - (np.log(np.exp(log_w - peak).sum()) + peak)
    return np.maximum(out, MIN_LOG_MU)


def logsumexp_finite(a: np.ndarray) -> float:
    """:func:`logsumexp` of a finite 1-D array, the same operations without the masks."""
    peak = a.max()
    return np.log(np.exp(a - peak).sum()) + peak


def first_argmax_mismatch(mu_history, reference: int, start: int = 0):
    """First row index ≥ ``start`` whose arg-max μ is not ``reference``; None if never.

    Rows that are all NaN (before selection started) are skipped.
    """
    mu = np.asarray(mu_history, dtype=float)
    for t in range(start, mu.shape[0]):
        row = mu[t]
        if np.all(np.isnan(row)):
            continue
        if int(np.nanargmax(row)) != reference:
            return t
    return None
