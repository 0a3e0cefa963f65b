"""The one frame loop every SLAM filter runs, with the per-landmark rule as a policy (SPEC 5.1, 6).

:func:`run_slam` drives the shared core (:class:`~stslam.slam.core.SlamState`)
over one sequence (:class:`~stslam.slam.inputs.SlamInputs`). What differs
between filters is how they treat landmarks, and that is the policy's
(:class:`FramePolicy`): which block a new landmark gets, which observations
update the state and whether a gate rejects them, and, for A-SLAM, block
conversions, restarts and model selection around the update. Per frame k:

1. k ≥ 1: predict with the control of step k − 1, its assumed covariance S
   and δt (SPEC 5.1);
2. ``before_update``: the policy may use some of the frame's observations
   otherwise (A-SLAM re-initialises converted blocks from them);
3. ``update``: the other observations of landmarks in the state update it;
   the policy reports which it accepted (the rest count as rejected);
4. ``after_update``: the policy reacts to the outcome (A-SLAM's restarts);
5. ``add_landmark`` for every landmark seen for the first time, in the
   frame's order;
6. ``after_frame``: the policy sees the posterior (A-SLAM feeds its selectors);
7. the pose and its covariance are recorded, and ``observer(k, state)`` is called.

With ``observe_every`` = N > 1, steps 2–5 run only at the frames k that are
multiples of N: the estimator takes observations at those frames and only
odometry in between (a smoother over tracked features whose errors persist
for many frames would otherwise count one error many times over; SPEC 14).
Steps 6–7 run at every frame, ``after_frame`` with the observations of the
landmarks already in the state, so A-SLAM's selectors are fed as often as
without it.

:class:`BlockPolicy` is the policy of the baselines: one block per landmark
from first sight, all observations of a frame in one joint update, optionally
each gated on its own NIS.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from stslam.slam.core import SlamState
from stslam.slam.inputs import SlamInputs, as_inputs


@dataclass(frozen=True, eq=False)
class Frame:
    """One frame's observations as the policy's hooks receive them.

    Attributes
    ----------
    k : int
        Frame index (0 = the known first pose).
    ids : list of int, length m
        Landmark ids seen, in the order of the inputs.
    zs : numpy.ndarray, shape (m, 3)
        Their observations z (m, robot frame), SPEC 5.2.
    Rs : numpy.ndarray, shape (m, 3, 3)
        Their noise covariances R (m², robot frame).
    """

    k: int
    ids: list
    zs: np.ndarray
    Rs: np.ndarray


class FramePolicy(Protocol):
    """How a filter treats landmarks; :func:`run_slam` calls these hooks in this order every frame.

    Observations are referred to by their index j in the frame (``frame.ids[j]``).
    """

    def before_update(self, state: SlamState, frame: Frame) -> set:
        """Indices j of observations used otherwise this frame, left out of the update."""

    def update(self, state: SlamState, frame: Frame, skip: set) -> dict:
        """Update with the observations of landmarks in the state (j not in ``skip``); j → accepted."""

    def after_update(self, state: SlamState, frame: Frame, outcome: dict) -> None:
        """React to the update's ``outcome`` (j → accepted)."""

    def add_landmark(self, state: SlamState, landmark_id: int, z_robot: np.ndarray, R: np.ndarray) -> None:
        """Put a landmark seen for the first time into the state, initialised from z (3,) with R (3, 3)."""

    def after_frame(self, state: SlamState, frame: Frame) -> None:
        """Last look at the frame's posterior, before the pose is recorded."""

    def track(self, poses_xytheta: np.ndarray, pose_covs: np.ndarray, n_rejected: int):
        """The run's result from the recorded poses (n, 3), covariances (n, 3, 3) and rejection count."""


@dataclass(frozen=True)
class BlockPolicy:
    """The baselines' rule: ``block_for(landmark id)`` at first sight, a joint update, an optional gate.

    Attributes
    ----------
    block_for : callable
        Landmark id → block object (:mod:`stslam.slam.blocks`), called at its first sighting.
    max_nis : float or None
        Bound on each observation's own NIS yᵀS⁻¹y (None: every observation is used).
    """

    block_for: Callable
    max_nis: float | None = None

    def before_update(self, state: SlamState, frame: Frame) -> set:
        return set()

    def update(self, state: SlamState, frame: Frame, skip: set) -> dict:
        """The known landmarks' observations in one joint update, each with its R (``SlamState.update_landmarks``)."""
        known = [j for j, i in enumerate(frame.ids) if i in state and j not in skip]
        if not known:
            return {}
        accepted, _ = state.update_landmarks([frame.ids[j] for j in known], frame.zs[known], frame.Rs[known],
                                             self.max_nis)
        return dict(zip(known, accepted.tolist()))

    def after_update(self, state: SlamState, frame: Frame, outcome: dict) -> None:
        return None

    def add_landmark(self, state: SlamState, landmark_id: int, z_robot: np.ndarray, R: np.ndarray) -> None:
        state.add_landmark(landmark_id, self.block_for(landmark_id), z_robot, R)

    def after_frame(self, state: SlamState, frame: Frame) -> None:
        return None

    def track(self, poses_xytheta: np.ndarray, pose_covs: np.ndarray, n_rejected: int) -> FilterTrack:
        return FilterTrack(poses_xytheta, pose_covs, n_rejected)


@dataclass(frozen=True)
class FilterTrack:
    """What a filter run produced.

    Attributes
    ----------
    poses_xytheta : numpy.ndarray, shape (n_frames, 3)
        Posterior robot pose per frame (after that frame's observations).
    pose_covs : numpy.ndarray, shape (n_frames, 3, 3)
        Their covariances (world frame).
    n_rejected : int
        Observations the gate rejected.
    """

    poses_xytheta: np.ndarray
    pose_covs: np.ndarray
    n_rejected: int


def run_slam(inputs: SlamInputs, policy: FramePolicy, motion_order: int = 2, update_iterations: int = 1,
             observer: Callable | None = None, state=None, observe_every: int = 1):
    """Run one filter over a sequence from its known first pose (zero covariance), frame by frame.

    The steps of each frame are those of the module docstring.

    Parameters
    ----------
    inputs : SlamInputs or SimulatedRun
    policy : FramePolicy
        The filter's landmark rule; a stateful one (A-SLAM's) serves one run.
    motion_order, update_iterations : int
        As in :class:`~stslam.slam.core.SlamState`.
    observer : callable, optional
        ``observer(k, state)`` after each frame (diagnostics; it must not change the state).
    state : optional
        The estimator, at the first pose: by default ``policy.new_state(pose, cov, motion_order,
        update_iterations)`` when the policy has one (A-SLAM's), else a fresh
        :class:`~stslam.slam.core.SlamState` (EKF); or anything that answers the same calls (:class:`stslam.graph.state.GraphState`).
    observe_every : int
        Observations update the state at every this many frames only (module docstring); 1: every frame.

    Returns
    -------
    Whatever ``policy.track`` makes of the poses (n, 3), their covariances (n, 3, 3, world
    frame) and the number of rejected observations (:class:`FilterTrack` for :class:`BlockPolicy`).
    """
    inputs = as_inputs(inputs)
    n = inputs.n_frames
    if isinstance(observe_every, bool) or not isinstance(observe_every, (int, np.integer)) or observe_every < 1:
        raise ValueError(f"observe_every: expected an integer ≥ 1, got {observe_every!r}")
    if state is None:  # a policy may bring its own kind of EKF state (A-SLAM's bodies)
        make = getattr(policy, "new_state", SlamState)
        state = make(inputs.initial_pose_xytheta, np.zeros((3, 3)), motion_order, update_iterations)
    poses, covs = np.empty((n, 3)), np.empty((n, 3, 3))
    rejected = 0
    for k in range(n):
        if k > 0:
            state.predict(inputs.controls_vw[k - 1], inputs.control_covs[k - 1], float(inputs.dts_s[k - 1]))
        frame = Frame(k, [int(i) for i in inputs.observation_ids[k]], inputs.observations[k],
                      inputs.observation_covs[k])
        if k % observe_every == 0:
            skip = policy.before_update(state, frame)
            outcome = policy.update(state, frame, skip)
            rejected += len(outcome) - sum(outcome.values())
            policy.after_update(state, frame, outcome)
            for j, i in enumerate(frame.ids):
                if i not in state:
                    policy.add_landmark(state, i, frame.zs[j], frame.Rs[j])
        else:  # between observing frames: the policy sees the landmarks it knows, the state only odometry
            known = [j for j, i in enumerate(frame.ids) if i in state]
            frame = Frame(k, [frame.ids[j] for j in known], frame.zs[known], frame.Rs[known])
        policy.after_frame(state, frame)
        poses[k], covs[k] = state.pose, state.pose_cov
        if observer is not None:
            observer(k, state)
    return policy.track(poses, covs, rejected)
