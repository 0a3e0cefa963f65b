"""Fitting an order-k filter to a trace: initialisation and maximum-likelihood noise (SPEC 3, 8.2)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.errors import ConfigError
from stslam.kalman.temporal import initial_covariance, transition_matrices
from stslam.kalman.trace_fit import FilterSettings, fit_order, run_filter, tune_noise

TUNED = FilterSettings(process_noise="taylor", initial_covariance="estimator", tune=True,
                       sigma_eta=0.1, sigma_obs=0.1, window=5, smoothing_sigma=2.0)


def _simulate(n, order, sigma_eta, sigma_obs, rng):
    """A trace drawn from the order-k model itself (SPEC 3), observed with white noise."""
    A, B = transition_matrices(order, 1.0)
    x, q = np.zeros(order + 1), np.empty(n)
    for i in range(n):
        x = A @ x + B * sigma_eta * rng.standard_normal()
        q[i] = x[0]
    return np.arange(n, dtype=float), q + sigma_obs * rng.standard_normal(n)


def _log_likelihood(times, z, order, settings, sigma_eta, sigma_obs):
    return float(np.nansum(run_filter(times, z, order, settings, sigma_eta, sigma_obs).log_likelihood))


def test_maximum_likelihood_recovers_the_noise_of_a_simulated_trace():
    estimates = np.array([tune_noise(*_simulate(200, 1, 0.05, 0.3, np.random.default_rng(seed)), 1, TUNED)
                          for seed in range(3)])
    # Over 12 such traces (seeds 0–11, measured once) the estimates spread with
    # standard deviations 0.0125 (σ_η) and 0.016 (σ_obs) about means 0.047 and
    # 0.298; the mean of 3 traces is then within 4·s/√3 of the truth unless the
    # estimator is broken: ±0.029 for σ_η = 0.05, ±0.037 for σ_obs = 0.3.
    assert estimates[:, 0].mean() == pytest.approx(0.05, abs=0.029)
    assert estimates[:, 1].mean() == pytest.approx(0.3, abs=0.037)


def test_tuned_noise_is_a_local_maximum_of_the_likelihood():
    times, z = _simulate(60, 2, 0.02, 0.2, np.random.default_rng(7))
    sigma_eta, sigma_obs = tune_noise(times, z, 2, TUNED)
    best = _log_likelihood(times, z, 2, TUNED, sigma_eta, sigma_obs)
    # Nelder–Mead stops within xatol = 1e-3 in log σ; 5% steps are well outside it.
    for factor_eta, factor_obs in [(1.05, 1), (0.95, 1), (1, 1.05), (1, 0.95)]:
        assert best >= _log_likelihood(times, z, 2, TUNED, sigma_eta * factor_eta, sigma_obs * factor_obs)


def test_estimator_initial_covariance_and_untuned_settings_are_used():
    times, z = _simulate(30, 1, 0.05, 0.3, np.random.default_rng(2))
    fixed = FilterSettings(process_noise="identity", initial_covariance="estimator", sigma_eta=0.1,
                           sigma_obs=0.4, window=6, smoothing_sigma=1.0)
    fit = fit_order(times, z, 1, fixed, horizon=2)
    assert (fit.sigma_eta, fit.sigma_obs) == (0.1, 0.4)
    assert fit.result.start == 5
    P0 = initial_covariance(6, 1, 1.0, 1.0, 0.4)
    np.testing.assert_allclose(fit.result.variances[5], np.diag(P0), rtol=1e-12)


def test_window_must_hold_the_order():
    times, z = _simulate(30, 1, 0.05, 0.3, np.random.default_rng(2))
    with pytest.raises(ValueError, match=r"^settings.window: expected ≥ 4 samples to initialise order 3, got 3$") \
            as caught:
        run_filter(times, z, 3, FilterSettings(window=3), 0.1, 0.1)
    assert not isinstance(caught.value, ConfigError)  # the experiment names filter.window
    with pytest.raises(ValueError, match=r"^times, z: expected matching shapes with more than settings.window = 30"):
        run_filter(times, z, 1, FilterSettings(window=30), 0.1, 0.1)


@pytest.mark.parametrize("field, value, match", [
    ("window", 1, r"^window: expected an integer ≥ 2, got 1$"),
    ("window", 2.0, r"^window: expected an integer ≥ 2, got 2.0$"),
    ("smoothing_sigma", 0.0, r"^smoothing_sigma: expected a finite number > 0, got 0.0$"),
    ("sigma_obs", float("nan"), r"^sigma_obs: expected a finite number > 0, got nan$"),
    ("process_noise", "white", r"^process_noise: expected one of identity, taylor; got 'white'$"),
    ("initial_covariance", "flat", r"^initial_covariance: expected one of identity, estimator; got 'flat'$"),
])
def test_settings_name_their_own_bad_field(field, value, match):
    with pytest.raises(ValueError, match=match) as caught:
        FilterSettings(**{field: value})
    assert not isinstance(caught.value, ConfigError)  # the config edge names filter.<field>
