"""One simulated SLAM run: true controls, noisy odometry and observations (SPEC 5, 8.4).

Everything random comes from one ``numpy.random.Generator`` in a fixed order:
first 2·(n_frames − 1) standard normals for the odometry noise, then
3·n_frames·n_landmarks for the observation noise (drawn for every landmark in
every frame, visible or not). The draws do not depend on the field of view or
on whether control noise is switched on, so the authors' variants see the
same noise as the default run of the same seed (common random numbers).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stslam.robot.motion import control_between, control_noise_cov, sample_noisy_controls
from stslam.robot.sensor import Sensor, observation_noise, observe
from stslam.sim.worlds import World


@dataclass(frozen=True, eq=False)
class SimulatedRun:
    """Inputs a filter sees, with the ground truth beside them.

    Attributes
    ----------
    world : World
        Ground truth (poses, landmark positions, models).
    controls_true : numpy.ndarray, shape (n_frames − 1, 2)
        Control (v m/s, ω rad/s) that moves the true pose of frame k to frame k + 1.
    controls_odometry : numpy.ndarray, shape (n_frames − 1, 2)
        What the filters receive: the true control plus N(0, S(u)) (SPEC 5.1) when
        control noise is on, else the true control (the authors' setting).
    observation_ids : tuple[numpy.ndarray, ...]
        Per frame, indices (k,) of the visible landmarks into ``world.landmarks``.
    observations : tuple[numpy.ndarray, ...]
        Per frame, their observations z (k, 3) in the robot frame (m), noisy.
    sensor : Sensor
    """

    world: World
    controls_true: np.ndarray
    controls_odometry: np.ndarray
    observation_ids: tuple
    observations: tuple
    sensor: Sensor

    def control_cov(self, k: int) -> np.ndarray:
        """Control noise covariance S(û) the filters assume at step k → k + 1, shape (2, 2)."""
        return control_noise_cov(self.controls_odometry[k], self.world.alpha)


def true_controls(poses_xytheta, dt: float) -> np.ndarray:
    """Controls between consecutive true poses (inverse of SPEC 5.1), shape (n − 1, 2)."""
    poses = np.asarray(poses_xytheta, dtype=float)
    return np.array([control_between(poses[k], poses[k + 1], dt) for k in range(poses.shape[0] - 1)])


def simulate(world: World, sensor: Sensor, rng: np.random.Generator, control_noise: bool = True) -> SimulatedRun:
    """Draw odometry and observations for ``world`` (known data association, SPEC 5.2).

    Visibility is decided on the noise-free relative position; the observation
    is z = R(θ)ᵀ(m − [x, y, 0]ᵀ) + σ·ε with ε ~ N(0, I₃).
    """
    n = world.n_frames
    u_true = true_controls(world.poses_xytheta, world.dt)
    u_noisy = sample_noisy_controls(u_true, world.alpha, rng)
    u_odometry = u_noisy if control_noise else u_true.copy()
    noise = observation_noise(rng, sensor.sigma_m, (n, world.n_landmarks, 3))
    ids, zs = [], []
    for k in range(n):
        z_true = observe(world.poses_xytheta[k], world.positions[k])
        visible = np.flatnonzero(sensor.fov.contains(z_true))
        ids.append(visible)
        zs.append(z_true[visible] + noise[k, visible])
    return SimulatedRun(world, u_true, u_odometry, tuple(ids), tuple(zs), sensor)
