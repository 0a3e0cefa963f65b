"""Process-noise grid search and the tuning file it writes (SPEC 8.4)."""

from __future__ import annotations

import importlib.util

import numpy as np
import yaml

from stslam.config.robot import sensor_from_config
from stslam.config.sim import world_from_config
from stslam.config.slam import filter_params_from_config
from stslam.slam.tuning import TUNED_PARAMETERS, grid_search

from conftest import REPO, compose_config


def _tune_script():
    spec = importlib.util.spec_from_file_location("tune_script", REPO / "experiments" / "tune.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_grid_search_scans_the_full_product_and_sorts_by_mean_ate():
    cfg = compose_config("dynamic_slam", ["world.n_frames=30"])
    world, sensor = world_from_config(cfg), sensor_from_config(cfg)
    table = grid_search(filter_params_from_config(cfg, "oracle"), "oracle", world, sensor, True, seeds=[1000, 1001],
                        motion_order=2, iterations=1, grid=(0.0, 0.01, 0.3))
    assert len(table) == 9 and list(table.columns[:2]) == ["sigma_eta_m", "sigma_eta_rad"]
    assert np.all(np.diff(table["mean_ate_m"]) >= 0)
    assert set(map(tuple, table[["sigma_eta_m", "sigma_eta_rad"]].to_numpy())) == {
        (a, b) for a in (0.0, 0.01, 0.3) for b in (0.0, 0.01, 0.3)}
    # Same seeds, same setting: the search is deterministic.
    again = grid_search(filter_params_from_config(cfg, "oracle"), "oracle", world, sensor, True, seeds=[1000, 1001],
                        motion_order=2, iterations=1, grid=(0.0, 0.01, 0.3))
    assert table.equals(again)


def test_tuning_file_round_trips_and_keeps_untuned_methods():
    cfg = compose_config("dynamic_slam", ["world.n_frames=30"])
    world, sensor = world_from_config(cfg), sensor_from_config(cfg)
    tables = {"ekf_slam": grid_search(filter_params_from_config(cfg, "ekf_slam"), "ekf_slam", world, sensor, True,
                                      seeds=[1000], motion_order=2, iterations=1, grid=(0.0, 0.01))}
    # An existing file: the oracle's block (with its comments) must survive a run that tunes ekf_slam only.
    previous = ("# @package _global_\nfilters:\n  # python experiments/tune.py world=square_centred 'methods=[oracle]'\n"
                "  # oracle: mean ATE 0.0186 m at the best setting; next best:\n"
                "  oracle: {sigma_eta_m: 0.001, sigma_eta_rad: 0.3}\n  ekf_slam: {sigma_walk: 0.5}\n")
    command = "python experiments/tune.py world=square_centred 'methods=[ekf_slam]'"
    text = _tune_script().tuning_yaml("square_centred", command, [1000], tables, previous)
    assert text.startswith("# @package _global_\n")
    filters = yaml.safe_load(text)["filters"]
    best = tables["ekf_slam"].iloc[0]
    assert filters["ekf_slam"] == {"sigma_walk": float(best["sigma_walk"])}
    assert filters["oracle"] == {"sigma_eta_m": 0.001, "sigma_eta_rad": 0.3}
    assert set(filters) == {"ekf_slam", "oracle"} and set(TUNED_PARAMETERS) >= set(filters)
    assert "  # oracle: mean ATE 0.0186 m at the best setting; next best:" in text.splitlines()
    assert f"  # {command}" in text.splitlines()


def test_fixed_settings_on_the_command_line_are_written_into_the_tuned_block():
    # A setting the values were tuned for (the oracle's order) must be in the file beside them,
    # or regenerating the file would lose it; overrides of other methods or tuned names are not fixed.
    script = _tune_script()
    argv = ["world=kitchen", "methods=[oracle]", "filters.oracle.order=0", "filters.oracle.sigma_eta_static_m=0.0",
            "filters.oracle.sigma_eta_m=0.5", "filters.ekf_slam.sigma_walk=0.1"]
    fixed = script.fixed_settings(argv, {"oracle"})
    assert fixed == {"oracle": {"order": "0", "sigma_eta_static_m": "0.0"}}
    cfg = compose_config("dynamic_slam", ["world.n_frames=30"])
    world, sensor = world_from_config(cfg), sensor_from_config(cfg)
    tables = {"oracle": grid_search(filter_params_from_config(cfg, "oracle"), "oracle", world, sensor, True,
                                    seeds=[1000], motion_order=2, iterations=1, grid=(0.0, 0.01))}
    text = script.tuning_yaml("kitchen", "python experiments/tune.py " + " ".join(argv), [1000], tables, "", fixed)
    block = yaml.safe_load(text)["filters"]["oracle"]
    best = tables["oracle"].iloc[0]
    assert block == {"order": 0, "sigma_eta_static_m": 0.0, "sigma_eta_m": float(best["sigma_eta_m"]),
                     "sigma_eta_rad": float(best["sigma_eta_rad"])}
