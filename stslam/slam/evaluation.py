"""Run filters on one seed of a world and score them (SPEC 6.4, 7, 8.4).

Shared by the ``dynamic_slam`` experiment and the process-noise tuning so that
both score filters the same way: ATE and RPE (δ = 1 frame) from
:mod:`stslam.eval.metrics` on TUM rows, the time-averaged robot-pose NEES, and a
divergence flag (:func:`nees_divergence`) so that a filter that has lost
consistency says so in metrics.csv instead of silently reporting numbers.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from stslam.eval.metrics import ate_rmse, rpe_rmse
from stslam.robot.sensor import Sensor
from stslam.sim.simulate import SimulatedRun, simulate
from stslam.slam.consistency import pose_nees
from stslam.slam.filters import FilterTrack
from stslam.io.tum import tum_from_planar
from stslam.sim.worlds import World

# Divergence (SPEC 6.4): a frame is "out" when its robot-pose NEES exceeds the
# single-frame χ²₃ bound at probability DIVERGENCE_PROBABILITY (16.27; a consistent filter
# exceeds it on 0.1% of frames); a run is flagged when more than DIVERGENCE_FRACTION of its
# frames are out and at least DIVERGENCE_RUN of them in a row. A filter whose covariance is
# understated by a constant factor c is out on a third of its frames when 16.27/c is the
# 2/3-quantile of χ²₃ (3.40), i.e. c ≈ 4.8: the flag means a covariance ~5× too small
# throughout, or a filter lost for a third of the run. The thresholds sit between the
# healthy filters of every world (a quarter of frames out at most) and the lost ones
# (over a third, in long runs).
DIVERGENCE_PROBABILITY = 0.999
DIVERGENCE_FRACTION = 1.0 / 3.0
DIVERGENCE_RUN = 10


@dataclass(frozen=True)
class SeedResult:
    """One seed: the simulated inputs, each method's track, scores and wall-clock time.

    Made by :func:`run_seed`. ``dynamic_slam`` writes ``rows`` to metrics.csv and
    averages ``frame_nees`` over seeds for its consistency band; the benchmark
    reads ``seconds``.

    Attributes
    ----------
    seed : int
        The seed the world's noise was drawn with.
    run : SimulatedRun
        The simulated odometry and observations every method was given.
    tracks : dict[str, FilterTrack]
        Each method's estimate.
    rows : list[dict]
        One ``metrics.csv`` row per method: seed, method, ate_m, rpe_m, nees, nees_frac_out,
        diverged (see :func:`score_track`).
    frame_nees : dict[str, numpy.ndarray]
        Each method's robot-pose NEES per frame, frames ``NEES_FIRST_FRAME`` on (:func:`pose_nees`).
    seconds : dict[str, float]
        Wall-clock time of each method's run (s); kept out of metrics.csv, which
        must be byte-identical between runs.
    """

    seed: int
    run: SimulatedRun
    tracks: dict
    rows: list
    seconds: dict
    frame_nees: dict


def groundtruth_tum(world: World) -> np.ndarray:
    """TUM rows (n, 8) of the true robot path, time stamps k·δt (s)."""
    return tum_from_planar(np.arange(world.n_frames) * world.dt, world.poses_xytheta)


def track_tum(world: World, track: FilterTrack) -> np.ndarray:
    """TUM rows (n, 8) of a filter's pose estimates."""
    return tum_from_planar(np.arange(world.n_frames) * world.dt, track.poses_xytheta)


def longest_run(mask) -> int:
    """Length of the longest run of consecutive True values in a 1-D boolean array."""
    flags = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    edges = np.flatnonzero(np.diff(flags.astype(np.int8)))  # starts and ends alternate
    return int(np.max(edges[1::2] - edges[::2])) if edges.size else 0


def nees_divergence(nees_per_frame, dof: int = 3, probability: float = DIVERGENCE_PROBABILITY,
                    min_fraction: float = DIVERGENCE_FRACTION, min_run: int = DIVERGENCE_RUN) -> tuple[float, int]:
    """Fraction of frames whose NEES is beyond the single-frame χ² bound, and the divergence flag.

    Parameters
    ----------
    nees_per_frame : array_like, shape (n,)
        Robot-pose NEES per frame (χ²(dof) for a consistent filter, SPEC 6.4). A NaN
        (a singular or non-finite covariance) counts as out.
    dof : int
        Degrees of freedom per frame (3: x, y, θ).
    probability : float
        The bound is the χ²(dof) quantile at ``probability`` (0.999: 16.27 for 3 dof).
    min_fraction, min_run : float, int
        Flagged when more than ``min_fraction`` of the frames are out *and* at least
        ``min_run`` consecutive frames are (see the module constants for the choice).

    Returns
    -------
    (float, int)
        ``nees_frac_out`` in [0, 1] (NaN for no frames) and ``diverged`` (0 or 1).
    """
    nees = np.asarray(nees_per_frame, dtype=float)
    if nees.size == 0:
        return float("nan"), 0
    out = ~(nees <= chi2.ppf(probability, dof))  # NaN is out
    fraction = float(np.mean(out))
    return fraction, int(fraction > min_fraction and longest_run(out) >= min_run)


def score_track(world: World, track: FilterTrack, nees_per_frame, rpe_delta: int = 1) -> dict:
    """Scores of one track: ATE (m), RPE (m, δ = ``rpe_delta`` frames), mean robot NEES of its
    ``nees_per_frame`` (:func:`pose_nees`), and the divergence scores ``nees_frac_out`` and
    ``diverged`` of :func:`nees_divergence` (SPEC 6.4, 7). Whether the mean NEES lies in its band
    needs the frames' autocorrelation over all seeds: ``dynamic_slam`` adds that (``nees_in_band``)."""
    gt = groundtruth_tum(world)
    est = track_tum(world, track)
    frac_out, diverged = nees_divergence(nees_per_frame)
    return {"ate_m": ate_rmse(gt, est), "rpe_m": rpe_rmse(gt, est, delta=rpe_delta),
            "nees": float(np.mean(nees_per_frame)), "nees_frac_out": frac_out, "diverged": diverged}


def run_seed(world: World, sensor: Sensor, control_noise: bool, methods: Mapping[str, Callable], seed: int,
             rpe_delta: int = 1, observers: Mapping[str, Callable] | None = None) -> SeedResult:
    """Simulate seed ``seed`` (``default_rng(seed)``) and run every method on the same inputs.

    ``methods`` maps a method name to a callable ``SimulatedRun -> FilterTrack``; a method named in
    ``observers`` is called as ``method(run, observer=observers[name])`` (the frame loop's
    ``observer(k, state)``, which only reads the state).
    """
    run = simulate(world, sensor, np.random.default_rng(seed), control_noise)
    tracks, rows, seconds, frame_nees = {}, [], {}, {}
    for name, method in methods.items():
        start = time.perf_counter()
        track = method(run, observer=observers[name]) if observers and name in observers else method(run)
        seconds[name] = time.perf_counter() - start
        tracks[name] = track
        frame_nees[name] = pose_nees(world.poses_xytheta, track.poses_xytheta, track.pose_covs)
        rows.append({"seed": seed, "method": name, **score_track(world, track, frame_nees[name], rpe_delta)})
    return SeedResult(seed, run, tracks, rows, seconds, frame_nees)
