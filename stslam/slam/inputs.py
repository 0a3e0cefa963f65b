"""What a SLAM filter receives over one sequence, whatever produced it (SPEC 5.1, 5.2, 6).

Every filter of :mod:`stslam.slam` (the ``dynamic_slam`` baselines and A-SLAM)
is driven by one :class:`SlamInputs`: a known first pose, per step k → k+1 the
odometry control with the covariance S the filter assumes and the step's
duration, and per frame the ids, robot-frame observations and noise
covariances of the landmarks seen. Two sources build it:
:func:`inputs_from_run` (a simulated run, SPEC 5, 8.4) here, and
:func:`stslam.rgbd.slam_inputs.inputs_from_tracks` (RGB-D feature tracks, SPEC 8.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stslam.sim.simulate import SimulatedRun


@dataclass(frozen=True, eq=False)
class SlamInputs:
    """One sequence as a filter sees it (known data association).

    Attributes
    ----------
    initial_pose_xytheta : numpy.ndarray, shape (3,)
        Robot pose of frame 0 (x m, y m, θ rad, world frame), taken as known (P = 0).
    controls_vw : numpy.ndarray, shape (n − 1, 2)
        Odometry control (v m/s, ω rad/s) of step k → k + 1 (SPEC 5.1).
    control_covs : numpy.ndarray, shape (n − 1, 2, 2)
        Covariance S of each control that the filters assume ((m/s)², (rad/s)²).
    dts_s : numpy.ndarray, shape (n − 1,)
        Duration δt of each step (s; one frame where the world counts in frames).
    observation_ids : tuple of numpy.ndarray, each (k,)
        Per frame, the ids of the observed landmarks (ints).
    observations : tuple of numpy.ndarray, each (k, 3)
        Their observations z in the robot frame (m), SPEC 5.2.
    observation_covs : tuple of numpy.ndarray, each (k, 3, 3)
        Their noise covariances R (m², robot frame).
    """

    initial_pose_xytheta: np.ndarray
    controls_vw: np.ndarray
    control_covs: np.ndarray
    dts_s: np.ndarray
    observation_ids: tuple
    observations: tuple
    observation_covs: tuple

    def __post_init__(self):
        n = len(self.observation_ids)
        if n < 1 or len(self.observations) != n or len(self.observation_covs) != n:
            raise ValueError(f"SlamInputs: need ≥ 1 frame and as many observation arrays as id arrays; got "
                             f"{len(self.observation_ids)} / {len(self.observations)} / {len(self.observation_covs)}")
        if (np.shape(self.controls_vw) != (n - 1, 2) or np.shape(self.control_covs) != (n - 1, 2, 2)
                or np.shape(self.dts_s) != (n - 1,)):
            raise ValueError(f"SlamInputs: {n} frames need controls (n−1, 2), S (n−1, 2, 2) and δt (n−1,); got "
                             f"{np.shape(self.controls_vw)}, {np.shape(self.control_covs)}, {np.shape(self.dts_s)}")
        if np.shape(self.initial_pose_xytheta) != (3,):
            raise ValueError(f"SlamInputs: initial pose must have shape (3,), got {np.shape(self.initial_pose_xytheta)}")

    @property
    def n_frames(self) -> int:
        return len(self.observation_ids)

    @property
    def times_s(self) -> np.ndarray:
        """Time of each frame since frame 0, shape (n,) (s): 0 and the running sum of δt."""
        return np.concatenate([[0.0], np.cumsum(self.dts_s)])


def inputs_from_run(run: SimulatedRun) -> SlamInputs:
    """The inputs of a simulated run: odometry with S(û) (SPEC 5.1), R = the sensor's for every observation."""
    n = run.world.n_frames
    R = np.asarray(run.sensor.R, dtype=float)
    return SlamInputs(
        initial_pose_xytheta=np.asarray(run.world.poses_xytheta[0], dtype=float),
        controls_vw=np.asarray(run.controls_odometry, dtype=float).reshape(n - 1, 2),
        control_covs=np.array([run.control_cov(k) for k in range(n - 1)]).reshape(n - 1, 2, 2),
        dts_s=np.full(n - 1, float(run.world.dt)),
        observation_ids=run.observation_ids,
        observations=run.observations,
        observation_covs=tuple(np.broadcast_to(R, (len(ids), 3, 3)) for ids in run.observation_ids),
    )


def as_inputs(source) -> SlamInputs:
    """``source`` itself if it is :class:`SlamInputs`, else the inputs of a :class:`SimulatedRun`."""
    if isinstance(source, SlamInputs):
        return source
    if isinstance(source, SimulatedRun):
        return inputs_from_run(source)
    raise TypeError(f"expected SlamInputs or SimulatedRun, got {type(source).__name__}")
