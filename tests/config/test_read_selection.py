"""Model selection's settings read from ``selection`` (stslam.config.selection)."""

from __future__ import annotations

import pytest

from stslam.config.selection import selection_from_config
from stslam.errors import ConfigError
from stslam.selection.model_filter import FilterSettings
from stslam.selection.selector import ModelSelector

NAMES = ("static", "prismatic", "revolute")
PAPER_ETA = {"static": 0.001, "prismatic": 0.03, "revolute": 0.03}


def _config(**changes):
    block = {"selector": "threshold", "models": list(NAMES), "n_min": 7, "tau": 0.6, "hold_steps": 1,
             "min_motion_m": 0.0, "stay_probability": 0.98, "order": 1, "dt": 1.0,
             "measurement_sigma_m": 0.04, "smoothing_sigma": 3.0, "init_window": 7,
             "structure_inflation": 3.0, "sigma_eta": dict(PAPER_ETA), "static_perturbation": "paper",
             "min_radius_m": 0.0, "scale_cap_m": None, "fit_spacing_m": 0.0,
             "refit": {"enabled": True, "dense_until": 0, "growth": 1.2, "rerun_steps": 30}}
    block.update(changes)
    return {"selection": block}


def test_config_is_read_with_its_defaults():
    settings = selection_from_config(_config())
    assert settings.models == NAMES and settings.tau == 0.6 and settings.hold_steps == 1
    # Keys a config may leave out take their defaults: guards on, κ inflation.
    assert settings.support_alpha == 0.001 and settings.static_alpha == 0.05
    assert settings.filters["prismatic"].structure_uncertainty == "inflation"
    guards_off = selection_from_config(_config(support_alpha=None, static_alpha=None,
                                              structure_uncertainty="fisher"))
    assert guards_off.support_alpha is None and guards_off.static_alpha is None
    assert guards_off.filters["static"].structure_uncertainty == "fisher"
    assert settings.filters["revolute"] == FilterSettings(
        order=1, sigma_eta=0.03, measurement_sigma_m=0.04, smoothing_sigma=3.0, init_window=7,
        structure_inflation=3.0, rerun_steps=30, min_radius_m=0.0, scale_cap_m=float("inf"))
    # A model set is a config list: two models only.
    two = selection_from_config(_config(models=["static", "revolute"]))
    assert ModelSelector(two).names == ("static", "revolute")


@pytest.mark.parametrize("changes, message", [
    ({"tau": 1.5}, r"selection\.tau: expected a number > 0.0 and < 1.0"),
    ({"models": ["static", "hinge"]}, r"selection\.models\[1\]: expected one of"),
    ({"models": ["static", "static"]}, r"selection\.models: a model is listed twice"),
    ({"models": []}, r"selection\.models: expected a non-empty list"),
    ({"selector": "vote"}, r"selection\.selector: expected one of threshold, imm"),
    ({"sigma_eta": {"static": 0.1, "prismatic": 0.1}}, r"selection\.sigma_eta\.revolute: missing"),
    ({"n_min": 2}, r"selection\.n_min: expected an integer ≥ 3"),
    ({"hold_steps": 0}, r"selection\.hold_steps: expected an integer ≥ 1"),
    ({"smoothing_sigma": 0}, r"^selection\.smoothing_sigma: expected a number > 0.0, got 0.0$"),
    ({"scale_cap_m": -1.0}, r"selection\.scale_cap_m: expected a number > 0"),
    ({"support_alpha": 1.0}, r"selection\.support_alpha: expected a number > 0.0 and < 1.0"),
    ({"static_alpha": "often"}, r"selection\.static_alpha: expected a number"),
    ({"structure_uncertainty": "bootstrap"}, r"selection\.structure_uncertainty: expected one of inflation, fisher"),
])
def test_bad_config_values_name_the_key(changes, message):
    with pytest.raises(ConfigError, match=message):
        selection_from_config(_config(**changes))
