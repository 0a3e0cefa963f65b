"""Fit an order-k temporal filter to one observed trace of q (SPEC 3, 8.2).

Initialise the state from the first ``window`` samples (SPEC 3), optionally
choose the noise levels by maximum likelihood, and filter the rest of the
trace with :func:`stslam.kalman.trace_filter.filter_trace`.

Maximum likelihood: the innovations of a Kalman filter are independent given
the model, so log p(z_w … z_n | σ_η, σ_obs) = Σ_t log N(y_t; 0, S_t), the sum the
filter already reports. It is maximised over (log σ_η, log σ_obs) by
Nelder–Mead (deterministic, no gradients) inside ``LOG_SIGMA_BOUNDS``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from stslam.checks import check_choice, check_int, check_number
from stslam.kalman.trace_filter import PROCESS_NOISE_MODELS, TraceFilterResult, filter_trace
from stslam.kalman.temporal import derivative_operator

INITIAL_COVARIANCES = ("identity", "estimator")
# σ_η and σ_obs are searched between 1e-6 and 1e3 (units of q per s^(k+1) and of q).
LOG_SIGMA_BOUNDS = (np.log(1e-6), np.log(1e3))


@dataclass(frozen=True)
class FilterSettings:
    """How a trace is filtered (config group ``filter``, SPEC 8.2).

    Attributes
    ----------
    window : int
        Samples used to initialise the state (≥ k+1).
    smoothing_sigma : float
        Width of the Gaussian weights of the initial fit, in samples.
    process_noise : str
        ``"identity"`` (Q = σ_η² I, the paper's) or ``"taylor"`` (Q = σ_η² B Bᵀ, SPEC 3).
    sigma_eta : float
        Process-noise standard deviation (start value when tuned).
    sigma_obs : float
        Observation-noise standard deviation, R = σ_obs² (start value when tuned).
    initial_covariance : str
        ``"identity"`` (P0 = p0_var·I, the paper's) or ``"estimator"``
        (P0 = σ_obs² L Lᵀ, the covariance of the initial fit under white noise).
    p0_var : float
        Scale of the identity P0.
    tune : bool
        Choose σ_η and σ_obs per trace and order by maximum innovation likelihood.
    """

    window: int = 5
    smoothing_sigma: float = 0.6
    process_noise: str = "identity"
    sigma_eta: float = 0.1
    sigma_obs: float = 1.0
    initial_covariance: str = "identity"
    p0_var: float = 1.0
    tune: bool = False

    def __post_init__(self):
        check_int("window", self.window, low=2)
        for name in ("smoothing_sigma", "sigma_eta", "sigma_obs", "p0_var"):
            check_number(name, getattr(self, name), low=0, low_open=True)
        check_choice("process_noise", self.process_noise, PROCESS_NOISE_MODELS)
        check_choice("initial_covariance", self.initial_covariance, INITIAL_COVARIANCES)


@dataclass(frozen=True)
class OrderFit:
    """An order-k filter run on one trace: its noise levels and the filter output."""

    order: int
    sigma_eta: float
    sigma_obs: float
    result: TraceFilterResult


def _initial_state(times, z, order: int, settings: FilterSettings, sigma_obs: float):
    """x0 and P0 at sample window−1 (SPEC 3): local fit over the window's own times."""
    w = settings.window
    t = times[:w]
    L = derivative_operator(t, order, settings.smoothing_sigma * float(np.median(np.diff(t))))
    x0 = L @ z[:w]
    if settings.initial_covariance == "estimator":
        P0 = sigma_obs**2 * (L @ L.T)  # Cov(L z) under white noise
        P0 = 0.5 * (P0 + P0.T)
    else:
        P0 = settings.p0_var * np.eye(order + 1)
    return x0, P0


def run_filter(times, z, order: int, settings: FilterSettings, sigma_eta: float, sigma_obs: float,
               horizon: int = 1) -> TraceFilterResult:
    """Initialise on the first ``settings.window`` samples and filter the rest (SPEC 3, 8.2).

    Parameters
    ----------
    times, z : numpy.ndarray, shape (n,)
        Sample times (s, strictly increasing) and observations of q.
    order : int
        Temporal order k; the window must hold at least k+1 samples.
    sigma_eta, sigma_obs : float
        Noise standard deviations (see :class:`FilterSettings`).
    horizon : int
        Longest prediction horizon K scored (samples).

    Raises
    ------
    ValueError
        A window shorter than k+1 samples, or a trace no longer than the window.
    """
    times = np.asarray(times, dtype=float)
    z = np.asarray(z, dtype=float)
    if settings.window < order + 1:
        raise ValueError(f"settings.window: expected ≥ {order + 1} samples to initialise order {order}, "
                         f"got {settings.window}")
    if z.size < settings.window + 1 or times.shape != z.shape:
        raise ValueError(f"times, z: expected matching shapes with more than settings.window = "
                         f"{settings.window} samples, got {times.shape} and {z.shape}")
    x0, P0 = _initial_state(times, z, order, settings, sigma_obs)
    return filter_trace(times, z, x0, P0, settings.window - 1, sigma_eta, sigma_obs**2,
                        noise_model=settings.process_noise, horizon=horizon)


def tune_noise(times, z, order: int, settings: FilterSettings) -> tuple[float, float]:
    """(σ_η, σ_obs) maximising the summed innovation log-likelihood of the trace.

    Starts from ``settings.sigma_eta`` and ``settings.sigma_obs``; the search is
    over their logarithms, so both stay positive.
    """
    def negative_log_likelihood(log_sigmas):
        sigma_eta, sigma_obs = np.exp(log_sigmas)
        result = run_filter(times, z, order, settings, sigma_eta, sigma_obs)
        return -float(np.nansum(result.log_likelihood))

    start = np.log([settings.sigma_eta, settings.sigma_obs])
    start = np.clip(start, *LOG_SIGMA_BOUNDS)
    best = minimize(negative_log_likelihood, start, method="Nelder-Mead",
                    bounds=[LOG_SIGMA_BOUNDS, LOG_SIGMA_BOUNDS],
                    options={"xatol": 1e-3, "fatol": 1e-6, "maxiter": 400})
    sigma_eta, sigma_obs = np.exp(best.x)
    return float(sigma_eta), float(sigma_obs)


def fit_order(times, z, order: int, settings: FilterSettings, horizon: int = 1) -> OrderFit:
    """Noise levels (tuned or as configured) and the filter run of order k on one trace."""
    if settings.tune:
        sigma_eta, sigma_obs = tune_noise(times, z, order, settings)
    else:
        sigma_eta, sigma_obs = settings.sigma_eta, settings.sigma_obs
    result = run_filter(times, z, order, settings, sigma_eta, sigma_obs, horizon)
    return OrderFit(order, sigma_eta, sigma_obs, result)
