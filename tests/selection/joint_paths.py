"""Noisy point tracks of the three joint kinds, for the selection tests."""

from __future__ import annotations

import numpy as np


def joint_path(kind: str, travel, angle_per_unit: float, seed: int = 0, sigma_m: float = 0.002) -> np.ndarray:
    """Points (n, 3) (m) of a joint that has moved ``travel`` (n,) units, with N(0, σ²) noise.

    static: a fixed point; prismatic: 0.4 m per unit along (0.6, 0.8, 0); revolute: a
    circle of radius 0.5 m about z, ``angle_per_unit`` rad per unit.
    """
    rng = np.random.default_rng(seed)
    s = np.asarray(travel, dtype=float)
    if kind == "static":
        p = np.tile([0.3, -0.2, 1.1], (s.size, 1))
    elif kind == "prismatic":
        p = [0.3, -0.2, 1.1] + np.outer(0.4 * s, [0.6, 0.8, 0.0])
    else:
        a = angle_per_unit * s
        p = np.column_stack([0.5 * np.cos(a), 0.5 * np.sin(a), 0.1 * np.ones(s.size)])
    return p + rng.normal(0.0, sigma_m, p.shape)
