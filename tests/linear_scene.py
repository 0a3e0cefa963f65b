"""Test helper: a robot driving straight along x, so that motion and observations are linear in the state.

θ = 0 and ω = 0 exactly (the heading's noise is 0): the EKF's estimate is then the
exact posterior, and the graph back end must give the same numbers.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from stslam.robot.sensor import observe
from stslam.slam.inputs import SlamInputs


def straight_line_inputs(world_at: Callable, n: int, sigma: float, seed: int = 0) -> SlamInputs:
    """Inputs of ``n`` frames, 0.2 m apart, of the points ``world_at(k) -> (ids, points (m, 3))``.

    Each observation has noise ``sigma`` (m) per axis; the forward speed is
    0.2 m/frame with 0.01 m/frame of noise, the turn rate exactly 0. One
    generator of ``seed`` draws the observation noise frame by frame, then the controls.
    """
    rng = np.random.default_rng(seed)
    poses = np.column_stack([0.2 * np.arange(n), np.zeros(n), np.zeros(n)])
    ids, zs, Rs = [], [], []
    for k in range(n):
        seen, points = world_at(k)
        ids.append(np.array(seen))
        zs.append(observe(poses[k], points) + sigma * rng.standard_normal(points.shape))
        Rs.append(np.broadcast_to(sigma**2 * np.eye(3), (len(seen), 3, 3)))
    S = np.diag([0.01**2, 0.0])
    controls = np.column_stack([0.2 + 0.01 * rng.standard_normal(n - 1), np.zeros(n - 1)])
    return SlamInputs(poses[0], controls, np.broadcast_to(S, (n - 1, 2, 2)), np.ones(n - 1), tuple(ids),
                      tuple(zs), tuple(Rs))
