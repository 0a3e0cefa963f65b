"""The trace filter's settings read from ``filter`` (stslam.config.kalman)."""

from __future__ import annotations

import pytest

from stslam.config.kalman import trace_fit_from_config
from stslam.errors import ConfigError
from stslam.kalman.trace_fit import FilterSettings


def test_settings_from_config_checks_each_key():
    good = {"filter": {"window": 5, "smoothing_sigma": 0.6, "process_noise": "identity", "sigma_eta": 0.1,
                       "sigma_obs": 1.0, "initial_covariance": "identity", "p0_var": 1.0, "tune": False}}
    assert trace_fit_from_config(good) == FilterSettings()
    for key, value, match in [
        ("window", 1, r"filter.window: expected an integer ≥ 2, got 1"),
        ("smoothing_sigma", 0, r"filter.smoothing_sigma: expected a number > 0, got 0.0"),
        ("process_noise", "white", r"filter.process_noise: expected one of identity, taylor; got 'white'"),
        ("initial_covariance", "big", r"filter.initial_covariance: expected one of identity, estimator"),
        ("sigma_obs", -1.0, r"filter.sigma_obs: expected a number > 0, got -1.0"),
        ("tune", "yes", r"filter.tune: expected true or false, got 'yes'"),
    ]:
        bad = {"filter": {**good["filter"], key: value}}
        with pytest.raises(ConfigError, match=match):
            trace_fit_from_config(bad)
