"""Grid search of the filters' process noises on tuning seeds (SPEC 8.4: equal tuning effort).

Every filter's tuned parameters are scanned on the same grid of values (the
full product when a filter has two), each setting scored by the mean ATE over
the same tuning seeds, which must not overlap the evaluation seeds. Parameters
and their units:

* ``ekf_slam``, ``ekf_slam_gated``: ``sigma_walk`` — landmark random walk (m/√frame);
* ``dyn_slam``: ``sigma_acc`` — white acceleration (m/frame²), ``sigma_v0`` —
  prior velocity std (m/frame);
* ``oracle``: ``sigma_eta_m`` — noise on q̈ of static/prismatic landmarks
  (m/frame²), ``sigma_eta_rad`` — on φ̈ of revolute ones (rad/frame²).
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import replace

import numpy as np
import pandas as pd

from stslam.errors import StslamError
from stslam.eval.metrics import ate_rmse
from stslam.progress import progress
from stslam.robot.sensor import Sensor
from stslam.sim.simulate import simulate
from stslam.slam.evaluation import groundtruth_tum, track_tum
from stslam.slam.filters import make_filter, run_filter
from stslam.sim.worlds import World

TUNED_PARAMETERS = {
    "ekf_slam": ("sigma_walk",),
    "ekf_slam_gated": ("sigma_walk",),
    "dyn_slam": ("sigma_acc", "sigma_v0"),
    "oracle": ("sigma_eta_m", "sigma_eta_rad"),
    "a_slam": ("sigma_walk",),  # its static points' walk: the gated EKF's unless a world's tuning sets it
}
# Zero plus half-decade steps from 1e-4 to 0.3: the same 9 values for every parameter.
DEFAULT_GRID = (0.0, 1e-4, 3e-4, 1e-3, 3e-3, 1e-2, 3e-2, 1e-1, 3e-1)


def grid_search(params, method: str, world: World, sensor: Sensor, control_noise: bool, seeds: Sequence[int], *,
                motion_order: int, iterations: int, grid: Sequence[float] = DEFAULT_GRID,
                show_progress: bool = False) -> pd.DataFrame:
    """Mean and median ATE (m) of ``method`` for every grid setting of its tuned parameters.

    ``params`` (``FILTER_PARAMS[method]``) holds the method's fixed parameters; the tuned ones
    are replaced by each grid point. ``motion_order`` and ``iterations`` are those of
    :func:`~stslam.slam.filters.make_filter`. Every setting sees the same simulated seeds
    (``default_rng(seed)`` for each of ``seeds``).

    Returns
    -------
    pandas.DataFrame
        One row per setting: the tuned parameters, ``mean_ate_m``,
        ``median_ate_m``, sorted by mean ATE (best first; ties keep grid order).
    """
    names = TUNED_PARAMETERS[method]
    runs = [simulate(world, sensor, np.random.default_rng(s), control_noise) for s in seeds]
    gt = groundtruth_tum(world)
    rows = []
    settings = list(itertools.product(grid, repeat=len(names)))
    for values in progress(settings, f"tune {method}", total=len(settings), enabled=show_progress):
        trial = replace(params, **{name: float(value) for name, value in zip(names, values)})
        spec = make_filter(method, trial, world, motion_order, iterations)
        ates = [_ate_or_inf(gt, world, spec, run) for run in runs]
        rows.append({**dict(zip(names, values)), "mean_ate_m": float(np.mean(ates)),
                     "median_ate_m": float(np.median(ates))})
    table = pd.DataFrame(rows)
    return table.sort_values("mean_ate_m", kind="stable").reset_index(drop=True)


def _ate_or_inf(gt, world, spec, run) -> float:
    """ATE of one run; +inf when the setting makes the filter fail (e.g. S not positive definite)."""
    try:
        return ate_rmse(gt, track_tum(world, run_filter(spec, run)))
    except (StslamError, ValueError, np.linalg.LinAlgError):
        return float("inf")
