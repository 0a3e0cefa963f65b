"""Articulation model selection on three simulated landmarks (SPEC 8.3, paper §VII-C).

One static, one prismatic and one revolute point are observed by a static
sensor with Gaussian noise, one frame per time step; each landmark is run
through model selection (SPEC 4) from its first observation. The motions are
those of the paper's simulated world (SPEC 8.4): the prismatic point moves
1/30 m per frame along x, the revolute point turns π/5 rad per frame on a
circle of radius √200/30 m; σ_z = 0.04 m (SPEC 5.2). All are config values.

metrics.csv has one row per seed and landmark; ``method`` is the landmark's
true model (``static``, ``prismatic``, ``revolute``) so that summary.csv
summarises each landmark; the selector is in column ``selector``. Steps are
0-based frame indices; ``wrong_argmax_step`` is the first frame after the fit
at which arg-max μ is not the true model (NaN if never).
"""

from __future__ import annotations

from dataclasses import astuple

import numpy as np
import pandas as pd

from stslam.errors import ConfigError
from stslam.output import ExperimentOutput
from stslam.config.readers import get_float, get_float_list, get_int, lookup, run_settings
from stslam.experiments.seeds import SeedRunner
from stslam.render.articulation import frames_figure, mu_history_figure, table_figure
from stslam.robot.sensor import observation_noise, observe, world_from_robot
from stslam.selection.selector import ModelSelector
from stslam.config.selection import selection_from_config

LANDMARKS = ("static", "prismatic", "revolute")


def _read_config(cfg: dict) -> dict:
    key = "articulation"
    world = {
        "n_frames": get_int(cfg, f"{key}.n_frames", low=9),
        "noise_sigma_m": get_float(cfg, f"{key}.noise_sigma_m", low=0.0),
        "sensor_pose": np.array(get_float_list(cfg, f"{key}.sensor_pose", length=3)),
        "static_point": np.array(get_float_list(cfg, f"{key}.static_point", length=3)),
        "prismatic_start": np.array(get_float_list(cfg, f"{key}.prismatic_start", length=3)),
        "prismatic_velocity": np.array(get_float_list(cfg, f"{key}.prismatic_velocity", length=3)),
        "revolute_centre": np.array(get_float_list(cfg, f"{key}.revolute_centre", length=3)),
        "revolute_radius_m": get_float(cfg, f"{key}.revolute_radius_m", low=0.0, low_open=True),
        "revolute_rate_rad": get_float(cfg, f"{key}.revolute_rate_rad"),
        "predict_steps": get_int(cfg, f"{key}.predict_steps", low=1),
    }
    frames = lookup(cfg, f"{key}.frames")
    if not isinstance(frames, list) or not frames:
        raise ConfigError(f"{key}.frames: expected a non-empty list of frame indices, got {frames!r}")
    for i, _ in enumerate(frames):
        if isinstance(frames[i], bool) or not isinstance(frames[i], int) or not 0 <= frames[i] < world["n_frames"]:
            raise ConfigError(f"{key}.frames[{i}]: expected a frame index in [0, {world['n_frames'] - 1}], "
                              f"got {frames[i]!r}")
    world["frames"] = list(frames)
    return world


def landmark_paths(world: dict) -> dict[str, np.ndarray]:
    """True positions (n_frames, 3) of the three landmarks (m, world frame)."""
    t = np.arange(world["n_frames"], dtype=float)
    angle = world["revolute_rate_rad"] * t
    ring = np.column_stack([np.cos(angle), np.sin(angle), np.zeros_like(angle)])
    return {
        "static": np.tile(world["static_point"], (t.size, 1)),
        "prismatic": world["prismatic_start"] + np.outer(t, world["prismatic_velocity"]),
        "revolute": world["revolute_centre"] + world["revolute_radius_m"] * ring,
    }


def _run_landmark(settings, observations, frames, predict_steps, sensor_pose, snapshots: bool):
    """Selection over one landmark's observations; snapshots at ``frames`` when asked."""
    selector = ModelSelector(settings)
    shots = {}
    for t, z in enumerate(observations):
        selector.observe(z)
        if snapshots and t in frames:
            mu = selector.mu
            prediction = None
            if mu is not None:
                best = selector.names[int(np.argmax(mu))]
                prediction = world_from_robot(sensor_pose, selector.predicted_positions(best, predict_steps))
            shots[t] = {"trail": world_from_robot(sensor_pose, observations[:t + 1]), "mu": mu,
                        "prediction": prediction}
    return selector, shots


def run(cfg: dict, seeds: SeedRunner | None = None) -> ExperimentOutput:
    """Run ``n_seeds`` seeds of the three-landmark selection (SPEC 8.3); ``seeds`` runs them
    (:mod:`stslam.experiments.seeds`; None: one after another here)."""
    world = _read_config(cfg)
    settings = selection_from_config(cfg)
    seed0, n_seeds, show_progress = astuple(run_settings(cfg))
    paths = landmark_paths(world)
    names = settings.models

    def one_seed(k: int) -> list[tuple]:
        """Seed k: per landmark its row, μ history and (seed 0) snapshots."""
        rng = np.random.default_rng(seed0 + k)
        out = []
        for label in LANDMARKS:
            noise = observation_noise(rng, world["noise_sigma_m"], paths[label].shape)
            observations = observe(world["sensor_pose"], paths[label]) + noise  # SPEC 5.2
            selector, shots = _run_landmark(settings, observations, world["frames"], world["predict_steps"],
                                            world["sensor_pose"], snapshots=(k == 0))
            final = selector.mu if selector.mu is not None else np.full(len(names), np.nan)
            wrong = selector.wrong_argmax_step(label) if label in names else None
            out.append((label, {
                "seed": seed0 + k, "method": label, "selector": settings.selector,
                "chosen_model": selector.chosen or "undecided",
                "selection_step": np.nan if selector.chosen_step is None else selector.chosen_step,
                "correct": int(selector.chosen == label),
                **{f"mu_{n}": float(final[j]) for j, n in enumerate(names)},
                "wrong_argmax_step": np.nan if wrong is None else wrong,
            }, selector.mu_history, shots))
        return out

    rows, histories = [], {label: [] for label in LANDMARKS}
    shots_by_landmark = {}
    for k, landmarks in enumerate((seeds or SeedRunner()).map(one_seed, n_seeds, "articulation_estimation",
                                                              show_progress)):
        for label, row, history, shots in landmarks:
            if k == 0:
                shots_by_landmark[label] = shots
            histories[label].append(history)
            rows.append(row)
    metrics = pd.DataFrame(rows)
    table = selection_table(metrics)
    snapshots = [{"frame": t, "landmarks": {label: shots_by_landmark[label][t] for label in LANDMARKS}}
                 for t in world["frames"]]
    figures = {
        "frames": frames_figure(snapshots, names, sensor_xy=world["sensor_pose"][:2]),
        "mu_history": mu_history_figure({label: np.array(h) for label, h in histories.items()}, names,
                                        settings.tau),
        "selection_steps": table_figure(table, f"Selection ({settings.selector}, τ = {settings.tau}, "
                                               f"{n_seeds} seeds)"),
    }
    lines = [f"{r.landmark}: correct {r.correct_rate:.0%}, selection step mean {r.step_mean:.1f} "
             f"(range {r.step_min:.0f}–{r.step_max:.0f}), first wrong arg-max step median "
             f"{r.wrong_argmax_median:.0f}" for r in table.itertuples()]
    return ExperimentOutput(metrics=metrics, figures=figures, tables={"selection_steps": table}, lines=lines)


def selection_table(metrics: pd.DataFrame) -> pd.DataFrame:
    """Per landmark: correct rate, selection step mean/min/max, median first wrong arg-max step."""
    out = []
    for label, block in metrics.groupby("method", sort=False):
        steps = block["selection_step"].dropna()
        out.append({
            "landmark": label,
            "correct_rate": float(block["correct"].mean()),
            "step_mean": float(steps.mean()) if len(steps) else np.nan,
            "step_min": float(steps.min()) if len(steps) else np.nan,
            "step_max": float(steps.max()) if len(steps) else np.nan,
            "wrong_argmax_median": float(block["wrong_argmax_step"].median()),
            "wrong_argmax_seeds": int(block["wrong_argmax_step"].notna().sum()),
            "n": int(len(block)),
        })
    return pd.DataFrame(out)
