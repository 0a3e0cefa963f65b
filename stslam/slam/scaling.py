"""Timing helpers for the speed and scale benchmark (SPEC 11; run by ``experiments/bench.py``).

Not used by tests that time anything: benchmarks report, they do not assert.
"""

from __future__ import annotations

import time

import numpy as np

from stslam.robot.sensor import observe
from stslam.slam.blocks import StaticPointBlock
from stslam.slam.core import SlamState


def state_step_time(n_landmarks: int, n_observed: int = 7, n_steps: int = 30, seed: int = 0,
                    sigma_m: float = 0.04) -> float:
    """Median CPU seconds of one SLAM step (predict + joint update of ``n_observed`` landmarks).

    The state holds the robot and ``n_landmarks`` static points (3 states
    each), so the step's cost is measured as a function of the state size
    alone (the number of observations per step is fixed). Landmarks lie within
    4 m of the robot; the robot drives a slow circle.
    """
    rng = np.random.default_rng(seed)
    R = sigma_m**2 * np.eye(3)
    state = SlamState(np.zeros(3), 1e-6 * np.eye(3))
    angles = rng.uniform(-np.pi, np.pi, n_landmarks)
    ranges = rng.uniform(1.0, 4.0, n_landmarks)
    points = np.column_stack([ranges * np.cos(angles), ranges * np.sin(angles), rng.uniform(0, 0.3, n_landmarks)])
    block = StaticPointBlock(0.0)
    for i, point in enumerate(points):
        state.add_landmark(i, block, observe(state.pose, point) + rng.normal(0, sigma_m, 3), R)
    control = np.array([0.1, 0.05])
    control_cov = np.diag([1e-4, 1e-4])
    times = []
    for step in range(n_steps):
        ids = [(step * n_observed + j) % n_landmarks for j in range(min(n_observed, n_landmarks))]
        started = time.process_time()
        state.predict(control, control_cov, 1.0)
        zs = np.array([observe(state.pose, points[i]) for i in ids]) + rng.normal(0, sigma_m, (len(ids), 3))
        state.update_landmarks(ids, zs, R)
        times.append(time.process_time() - started)
    return float(np.median(times))


def loglog_slope(sizes, seconds) -> float:
    """Least-squares slope of log(seconds) against log(size): the empirical complexity exponent."""
    x = np.log(np.asarray(sizes, dtype=float))
    y = np.log(np.asarray(seconds, dtype=float))
    return float(np.polyfit(x, y, 1)[0])
