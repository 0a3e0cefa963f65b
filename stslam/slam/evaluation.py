"""Run filters on one seed of a world and score them (SPEC 6.4, 7, 8.4).

Shared by the ``dynamic_slam`` experiment and the process-noise tuning so that
both score filters the same way: ATE and RPE (δ = 1 frame) from
:mod:`stslam.metrics` on TUM rows, and the time-averaged robot-pose NEES.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from stslam.metrics import ate_rmse, rpe_rmse
from stslam.sensor import Sensor
from stslam.simulate import SimulatedRun, simulate
from stslam.slam.consistency import NEES_FIRST_FRAME, nees_band, pose_nees
from stslam.slam.filters import FilterTrack
from stslam.tum import tum_from_planar
from stslam.worlds import World


@dataclass(frozen=True)
class SeedResult:
    """One seed: the simulated inputs, each method's track, scores and wall-clock time.

    Attributes
    ----------
    seed : int
    run : SimulatedRun
    tracks : dict[str, FilterTrack]
    rows : list[dict]
        One ``metrics.csv`` row per method: seed, method, ate_m, rpe_m, nees, nees_in_band.
    seconds : dict[str, float]
        Wall-clock time of each method's run (s); kept out of metrics.csv, which
        must be byte-identical between runs.
    """

    seed: int
    run: SimulatedRun
    tracks: dict
    rows: list
    seconds: dict


def groundtruth_tum(world: World) -> np.ndarray:
    """TUM rows (n, 8) of the true robot path, time stamps k·δt (s)."""
    return tum_from_planar(np.arange(world.n_frames) * world.dt, world.poses_xytheta)


def track_tum(world: World, track: FilterTrack) -> np.ndarray:
    """TUM rows (n, 8) of a filter's pose estimates."""
    return tum_from_planar(np.arange(world.n_frames) * world.dt, track.poses_xytheta)


def score_track(world: World, track: FilterTrack, rpe_delta: int = 1) -> dict:
    """ATE (m), RPE (m, δ = ``rpe_delta`` frames) and mean robot NEES of one track, with the per-run band flag."""
    gt = groundtruth_tum(world)
    est = track_tum(world, track)
    nees = float(np.mean(pose_nees(world.poses_xytheta, track.poses_xytheta, track.pose_covs)))
    low, high = nees_band(world.n_frames - NEES_FIRST_FRAME)
    return {"ate_m": ate_rmse(gt, est), "rpe_m": rpe_rmse(gt, est, delta=rpe_delta), "nees": nees,
            "nees_in_band": int(low <= nees <= high)}


def run_seed(world: World, sensor: Sensor, control_noise: bool, methods: Mapping[str, Callable], seed: int,
             rpe_delta: int = 1) -> SeedResult:
    """Simulate seed ``seed`` (``default_rng(seed)``) and run every method on the same inputs.

    ``methods`` maps a method name to a callable ``SimulatedRun -> FilterTrack``.
    """
    run = simulate(world, sensor, np.random.default_rng(seed), control_noise)
    tracks, rows, seconds = {}, [], {}
    for name, method in methods.items():
        start = time.perf_counter()
        track = method(run)
        seconds[name] = time.perf_counter() - start
        tracks[name] = track
        rows.append({"seed": seed, "method": name, **score_track(world, track, rpe_delta)})
    return SeedResult(seed, run, tracks, rows, seconds)
