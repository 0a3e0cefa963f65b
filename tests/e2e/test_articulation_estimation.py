"""articulation_estimation (SPEC 8.3): a cut-down run and its table values."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from stslam.errors import ConfigError
from stslam.experiments import articulation_estimation
from stslam.experiments.runner import execute
from stslam.robot.sensor import observe, world_from_robot


def test_smoke_run_writes_metrics_table_and_figures(compose_exp):
    folder = execute(compose_exp("articulation_estimation", "n_seeds=6"))
    metrics = pd.read_csv(folder / "metrics.csv")
    assert len(metrics) == 18
    assert {"seed", "method", "selector", "selection_step", "correct", "mu_static", "mu_prismatic",
            "mu_revolute", "wrong_argmax_step"} <= set(metrics.columns)
    table = pd.read_csv(folder / "selection_steps.csv").set_index("landmark")
    # Reference: 50 seeds (seed 0..49) of the default config gave selection
    # step mean (sd) static 9.20 (1.41), prismatic 8.50 (1.13), revolute 7.00
    # (0.00), correct 100% on every landmark. On 200 seeds (0..199) no track
    # was declared wrongly and one static track (seed 108) stayed undecided.
    # With 6 seeds the mean may move by three standard errors, 3·sd/√6: ±1.8
    # (static) and ±1.4 (prismatic). SPEC 11 asks for the right model on every
    # seed; 599 of 600 right puts the miss rate below 0.8% (95% bound), under
    # 0.15 expected misses in these 18 tracks, so every one must be right.
    assert table.loc["static", "step_mean"] == pytest.approx(9.20, abs=1.8)
    assert table.loc["prismatic", "step_mean"] == pytest.approx(8.50, abs=1.4)
    assert table.loc["revolute", "step_mean"] == 7.0
    assert (table["correct_rate"] == 1.0).all()
    # Paper §VII-C: the static landmark takes longest.
    assert table.loc["static", "step_mean"] > table.loc["revolute", "step_mean"]
    # After 40 frames the true model's μ exceeded 0.9999 on all 50 reference seeds.
    for label in ("static", "prismatic", "revolute"):
        assert metrics.loc[metrics["method"] == label, f"mu_{label}"].min() > 0.999
    for name in ("frames", "mu_history", "selection_steps"):
        assert (folder / "figures" / f"{name}.png").stat().st_size > 0


def test_same_seed_gives_identical_metrics(compose_exp):
    short = ("n_seeds=2", "seed=3", "articulation.n_frames=15")
    first = execute(compose_exp("articulation_estimation", *short))
    second = execute(compose_exp("articulation_estimation", *short))
    assert (first / "metrics.csv").read_bytes() == (second / "metrics.csv").read_bytes()


def test_paths_follow_the_configured_motions(compose_exp):
    world = articulation_estimation._read_config(compose_exp("articulation_estimation"))
    paths = articulation_estimation.landmark_paths(world)
    np.testing.assert_allclose(np.diff(paths["prismatic"], axis=0), [[1 / 30, 0, 0]] * 39, atol=1e-4)
    radius = np.linalg.norm(paths["revolute"] - world["revolute_centre"], axis=1)
    np.testing.assert_allclose(radius, np.sqrt(200) / 30, atol=1e-4)
    z = observe(world["sensor_pose"], paths["static"])
    np.testing.assert_allclose(world_from_robot(world["sensor_pose"], z), paths["static"], atol=1e-12)


@pytest.mark.parametrize("override, message", [
    ("articulation.frames=[50]", r"articulation\.frames\[0\]: expected a frame index in \[0, 39\]"),
    ("articulation.noise_sigma_m=-1", r"articulation\.noise_sigma_m: expected a number ≥ 0"),
    ("selection.tau=1.5", r"selection\.tau: expected a number > 0.0 and < 1.0"),
])
def test_bad_overrides_are_config_errors(compose_exp, override, message):
    with pytest.raises(ConfigError, match=message):
        articulation_estimation.run(compose_exp("articulation_estimation", override))
