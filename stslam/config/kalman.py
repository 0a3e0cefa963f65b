"""How a door trace is filtered, from the ``filter`` block (``conf/filter/<option>.yaml``; SPEC 3, 8.2)."""

from __future__ import annotations

from collections.abc import Mapping

from stslam.config.readers import get_bool, get_choice, get_float, get_int
from stslam.kalman.trace_filter import PROCESS_NOISE_MODELS
from stslam.kalman.trace_fit import INITIAL_COVARIANCES, FilterSettings


def trace_fit_from_config(cfg: Mapping, prefix: str = "filter") -> FilterSettings:
    """Checked :class:`~stslam.kalman.trace_fit.FilterSettings` from the keys under ``prefix`` (ConfigError)."""
    key = prefix + "."
    return FilterSettings(
        window=get_int(cfg, key + "window", low=2),
        smoothing_sigma=get_float(cfg, key + "smoothing_sigma", low=0, low_open=True),
        process_noise=get_choice(cfg, key + "process_noise", PROCESS_NOISE_MODELS),
        sigma_eta=get_float(cfg, key + "sigma_eta", low=0, low_open=True),
        sigma_obs=get_float(cfg, key + "sigma_obs", low=0, low_open=True),
        initial_covariance=get_choice(cfg, key + "initial_covariance", INITIAL_COVARIANCES),
        p0_var=get_float(cfg, key + "p0_var", low=0, low_open=True),
        tune=get_bool(cfg, key + "tune"),
    )
