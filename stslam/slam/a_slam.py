"""A-SLAM: EKF SLAM whose landmarks take the articulation model selection chose for them (SPEC 6.3).

The shared core (:class:`~stslam.slam.core.SlamState`, one EKF for
everything) driven over :class:`~stslam.slam.inputs.SlamInputs`, plus a rule
per landmark (:class:`~stslam.slam.landmark_policy.LandmarkPolicy`: selection,
conversion, refinement, restarts), written for the two traps of SPEC 6.3.
Settings: :class:`~stslam.slam.a_slam_settings.ASlamParams`. The same code
runs ``dynamic_slam`` (simulation, δt one frame) and ``fridge`` (RGB-D tracks,
δt in s, per-observation R).

1. **From first sight** (trap (a)) a landmark is a static point (random walk
   ``sigma_walk``) whose observations must pass a χ² gate (3 dof), exactly as
   in ``ekf_slam_gated``: before any decision A-SLAM *is* the gated EKF.
2. **Selection, conversion, refinement** (trap (b)): see
   :mod:`stslam.slam.landmark_policy`.
3. **Relative motion.** When half or more of a frame's decided-static
   landmarks fail the gate, the robot is off, not they: after a trial update
   with all of them, those that then fit are used ungated (as the oracle
   would). A decided landmark rejected ``restart_after`` times in a row while
   other observations pass has moved (a door at rest that opens) or was lost:
   it is re-initialised from the current, unused observation — a static one
   as an undecided point under the same selector, an articulated one on its
   model — and reviewed again.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from scipy.stats import chi2

from stslam.robot.sensor import pose_induced_variance, world_from_robot, world_point_covariances
from stslam.geometry import rotation_z
from stslam.slam.bodies.policy import BodyLandmarkPolicy
from stslam.slam.bodies.state import BodySlamState
from stslam.slam.landmark_policy import LandmarkMark, LandmarkPolicy
from stslam.slam.a_slam_settings import ARTICULATED, ASlamParams
from stslam.slam.blocks import StaticPointBlock
from stslam.slam.core import SlamState
from stslam.slam.inputs import as_inputs
from stslam.slam.loop import Frame, run_slam
from stslam.slam.onsets import onsets
from stslam.slam.replay import ReplayHistory

__all__ = ["ASlamFramePolicy", "ASlamParams", "ASlamTrack", "LandmarkReport", "run_a_slam"]

@dataclass(frozen=True)
class LandmarkReport:
    """What A-SLAM did with one landmark.

    Attributes
    ----------
    model : str
        Its model at the end: ``undecided`` (still a gated static point),
        ``static``, ``prismatic`` or ``revolute`` (the block's model, one
        chosen and awaiting conversion, or one decided but not in ``convert``).
    decisions : tuple of (frame, step, model)
        Every decision: run frame, observation index of the landmark (0-based,
        counted from its first sighting across restarts) and chosen model.
    restarts, rebases, selector_failures, revisions : int
        Re-initialisations after repeated gate rejections; structure refits
        carried into the state; selectors replaced after a numerical failure;
        model switches made by the window evidence (:mod:`stslam.slam.bodies.decisions`).
    mu_frames : numpy.ndarray, shape (n,)
        Frames at which its selector received an observation.
    mu : numpy.ndarray, shape (n, r)
        Model probabilities after each (NaN before selection started), in the
        order of ``model_names``.
    model_names : tuple[str, ...]
    """

    model: str
    decisions: tuple
    restarts: int
    rebases: int
    selector_failures: int
    mu_frames: np.ndarray
    mu: np.ndarray
    model_names: tuple
    revisions: int = 0


@dataclass(frozen=True)
class ASlamTrack:
    """A-SLAM's pose track (the fields of :class:`stslam.slam.filters.FilterTrack`) and landmark reports.

    Attributes
    ----------
    poses_xytheta : numpy.ndarray, shape (n_frames, 3)
    pose_covs : numpy.ndarray, shape (n_frames, 3, 3)
    n_rejected : int
        Observations the gates rejected.
    landmarks : dict[int, LandmarkReport]
    """

    poses_xytheta: np.ndarray
    pose_covs: np.ndarray
    n_rejected: int
    landmarks: dict


# ---------------------------------------------------------------------- the run

class ASlamFramePolicy:
    """A-SLAM's hooks for :func:`stslam.slam.loop.run_slam` around one :class:`LandmarkPolicy` (one run).

    Per frame: convert landmarks whose articulated model was chosen since their
    last sighting (from this frame's observation); update with the other
    observations (gated; static points jointly, articulated ones each with its
    own R); restart decided landmarks rejected ``restart_after`` times in a
    row; add new landmarks as static points; feed the selectors. The
    selectors' nominal δt is ``classify_every`` median steps of ``inputs``;
    each observation carries its real gap.
    """

    def __init__(self, params: ASlamParams, inputs, moving: np.ndarray | None = None):
        inputs = as_inputs(inputs)
        # A bound's motion truth (the method a_slam_truth_onsets), bool (n_frames, n_landmarks): an observation
        # of a point held static taken while the point truly moves is held out as the onset tests hold out theirs.
        if moving is not None:
            moving = np.asarray(moving)
            if moving.dtype != bool or moving.ndim != 2 or moving.shape[0] < inputs.n_frames:
                raise ValueError(f"moving: expected a bool array (n_frames ≥ {inputs.n_frames}, n_landmarks), "
                                 f"got {moving.dtype} {moving.shape}")
        self.moving = moving
        step_s = float(np.median(inputs.dts_s)) if inputs.n_frames > 1 else 1.0
        self.params = replace(params, selection=params.selection.with_dt(params.classify_every * step_s))
        # SPEC 13: with ``bodies``, landmarks moving rigidly together share one motion state.
        self.landmarks = (LandmarkPolicy if params.bodies is None else BodyLandmarkPolicy)(self.params)
        self.times_s = inputs.times_s
        sigma = self.params.max_pose_sigma_m
        self.max_nis, self.max_pose_var = self.params.max_nis, np.inf if sigma is None else sigma ** 2
        # SPEC 18: roll the EKF back to a flagged point's onset and replay the frames since without it; a
        # smoother takes the point's factors of those frames out (stslam.graph.reread.withdraw)
        self.evidence_pose = None  # (frame, pose, its covariance) of _keep_evidence_pose
        self.history = (ReplayHistory(self.params.onset_replay, inputs.controls_vw, inputs.control_covs, inputs.dts_s)
                        if self.params.onset_replay and self.params.onset_allowance is not None else None)

    def before_update(self, state: SlamState, frame: Frame) -> set:
        """Convert pending landmarks from this frame's observation; the indices j so used."""
        marks, history = self.landmarks.marks, self._history(state)
        if history is not None:  # (the conversions are journaled into the frame's history)
            history.begin(frame.k, state)
        return {j for j, i in enumerate(frame.ids)
                if i in marks and marks[i].pending is not None
                and self.landmarks.convert(state, i, frame.zs[j], frame.Rs[j])}

    def update(self, state: SlamState, frame: Frame, skip: set) -> dict:
        marks, history = self.landmarks.marks, self._history(state)
        held, nis = onsets(state, frame, marks, skip, self.params, float(self.times_s[frame.k]))
        if self.moving is not None:
            held = self._truly_moving(state, frame, skip, held, nis)
        outcome = _update(state, frame.ids, frame.zs, frame.Rs, marks, skip | set(held),
                          self.max_nis, self.params.gate_probability, nis, history,
                          lambda: self._keep_evidence_pose(state, frame.k),
                          self.params.articulated_update == "joint")
        flagged = [frame.ids[j] for j in held if marks[frame.ids[j]].flagged == frame.k]
        starts = {i: frame.k if marks[i].rising is None else marks[i].rising for i in flagged}
        if flagged and history is not None:
            history.replay(state, flagged, min(starts.values()))
        elif flagged and self.params.onset_withdraw and hasattr(state, "withdraw"):  # a smoother: its factors since
            for i in flagged:
                state.withdraw(i, max(starts[i], frame.k - self.params.onset_withdraw))
        # a held-out point the gate would reject counts as rejected (its restarts re-place it); one the gate
        # would pass is left out of the count (a false alarm must not re-place a well-mapped point)
        outcome.update({j: False for j, passed in held.items() if not passed})
        return outcome

    def _truly_moving(self, state, frame: Frame, skip: set, held: dict, nis: dict | None) -> dict:
        """``held`` with every other static row j whose point truly moves at this frame (``self.moving``): held out,
        counted as rejected when its NIS fails the gate, as :func:`~stslam.slam.onsets.onsets` holds out its own."""
        marks, moving = self.landmarks.marks, self.moving[frame.k]
        rows = [j for j, i in enumerate(frame.ids) if i in state and j not in skip and j not in held
                and marks[i].status not in ARTICULATED and i < moving.size and moving[i]]
        if rows and nis is None:
            nis = dict(zip(rows, state.observation_nis([frame.ids[j] for j in rows], frame.zs[rows],
                                                       frame.Rs[rows]).tolist(), strict=True))
        return {**held, **{j: nis[j] <= self.max_nis for j in rows}}

    def _keep_evidence_pose(self, state, k: int) -> None:
        """Between the static points' update and the articulated landmarks' own: the EKF's pose then is the
        one the frame's sightings are kept with for the bodies (``BodySettings.evidence_pose`` "static")."""
        bodies = self.params.bodies
        if bodies is not None and bodies.evidence_pose == "static" and isinstance(state, SlamState):
            self.evidence_pose = (k, state.pose, state.pose_cov)

    def after_update(self, state: SlamState, frame: Frame, outcome: dict) -> None:
        """Count rejections of decided landmarks; restart those rejected ``restart_after`` times in a row."""
        n_accepted, history = sum(outcome.values()), self._history(state)
        if history is not None:
            history.watch(state)
        for j, ok in outcome.items():
            mark = self.landmarks.marks[frame.ids[j]]
            # A rejection counts against a decided landmark only while other observations of the
            # frame pass: when all fail, the robot is off, not the landmark.
            if ok or mark.status == "undecided" or n_accepted == 0:
                mark.rejections = 0
            else:
                mark.rejections += 1
            if mark.rejections >= self.params.restart_after:
                self.landmarks.restart(state, frame.ids[j], frame.zs[j], frame.Rs[j])
        if history is not None:  # a change not journaled ends the history
            history.check(state)

    def add_landmark(self, state: SlamState, landmark_id: int, z_robot, R) -> None:
        """A new landmark is an undecided static point."""
        state.add_landmark(landmark_id, self.landmarks.static_block, z_robot, R)
        self.landmarks.new_mark(landmark_id)  # (the addition is journaled: stslam.slam.replay)

    def after_frame(self, state: SlamState, frame: Frame) -> None:
        """Feed the selectors with the frame's points mapped to the world by the posterior pose (SPEC 5.2)."""
        policy, ids, zs, history = self.landmarks, frame.ids, frame.zs, self._history(state)
        if history is not None:  # selection's refits and bodies: journaled changes (else the history ends)
            history.begin(frame.k, state)  # (a frame without updates has no entry yet)
            history.watch(state)
        wanted = [j for j, i in enumerate(ids) if policy.wants(policy.marks[i])]
        if wanted and self.max_pose_var != np.inf:
            # Selection sees only points whose pose-induced error is small (landmark_policy docstring).
            near = pose_induced_variance(state.pose, state.pose_cov, zs[wanted]) <= self.max_pose_var
            wanted = [j for j, ok in zip(wanted, near, strict=True) if ok]
        covs = selection_covariances(state, frame, wanted, self.params.selection_covariance)
        points = world_from_robot(state.pose, zs[wanted])  # SPEC 5.2
        for j, m, cov in zip(wanted, points, covs, strict=True):
            policy.select(state, ids[j], m, frame.k, self.times_s, cov)
        if self.params.bodies is not None:
            kept = self.evidence_pose
            policy.group(state, frame, kept[1:] if kept is not None and kept[0] == frame.k else None)
        if history is not None:
            history.check(state)

    def _history(self, state) -> ReplayHistory | None:
        """The replay history when ``onset_replay`` is on and ``state`` is an EKF's."""
        return self.history if isinstance(state, SlamState) else None

    def new_state(self, pose_xytheta, pose_cov, motion_order: int, update_iterations: int) -> SlamState:
        """The EKF state of a run: one whose members may share a founder's block when ``bodies`` is set."""
        make = SlamState if self.params.bodies is None else BodySlamState
        return make(pose_xytheta, pose_cov, motion_order, update_iterations)

    def track(self, poses_xytheta, pose_covs, n_rejected: int) -> ASlamTrack:
        reports = {i: _report(m) for i, m in sorted(self.landmarks.marks.items())}
        return ASlamTrack(poses_xytheta, pose_covs, n_rejected, reports)


def run_a_slam(params: ASlamParams, inputs, observer: Callable | None = None,
               motion_order: int = 2, update_iterations: int = 1, moving: np.ndarray | None = None) -> ASlamTrack:
    """Run A-SLAM over one sequence (:class:`~stslam.slam.inputs.SlamInputs` or a SimulatedRun) from its first pose.

    :func:`stslam.slam.loop.run_slam` with an :class:`ASlamFramePolicy`;
    ``observer(k, state)``, if given, is called after each frame; ``motion_order`` and
    ``update_iterations`` as in :class:`~stslam.slam.core.SlamState`; ``moving`` (bool (n_frames, n_landmarks),
    :func:`~stslam.slam.decision_scores.truly_moving`), for a diagnostic only, holds out every observation of a
    point held static taken while it truly moves: what a perfect onset test would do (SPEC 18).
    """
    inputs = as_inputs(inputs)
    return run_slam(inputs, ASlamFramePolicy(params, inputs, moving), motion_order, update_iterations, observer)


def selection_covariances(state: SlamState, frame: Frame, wanted: list, kind: str) -> list:
    """Covariances (3, 3) (m², world) of the points ``frame.zs[wanted]`` given to selection (SPEC 13).

    ``kind`` (:class:`~stslam.slam.a_slam_settings.ASlamParams` ``selection_covariance``):
    ``"sensor"``, None each (the selector's σ_z² I); ``"pose"``, R(θ) R Rᵀ(θ) + J_pose P_pose J_poseᵀ;
    ``"relative"``, for a landmark held as a static point, R(θ) S R(θ)ᵀ with S = H P Hᵀ + R
    its innovation covariance against its own estimate in the state (SPEC 5.3, 6.3): the
    point was placed through the same drifting pose, so the part of the pose error the two
    share moves neither (it is no motion), and only the rest counts; for an articulated one,
    whose structure is fixed in the world and shares nothing with the pose, ``"pose"``. S is the
    state's ``innovation_covariances`` (the EKF's P, or the factor graph's joint marginal, one per frame).
    """
    if kind == "sensor" or not wanted:
        return [None] * len(wanted)
    covs = list(world_point_covariances(state.pose, state.pose_cov, frame.zs[wanted], frame.Rs[wanted]))
    if kind == "pose":
        return covs
    rot = rotation_z(state.pose[2])
    static = [n for n, j in enumerate(wanted) if isinstance(state.block(frame.ids[j]), StaticPointBlock)]
    rows = [wanted[n] for n in static]
    if rows:  # all at once: the factor graph then takes one joint marginal per frame
        Ss = state.innovation_covariances([frame.ids[j] for j in rows], frame.Rs[rows])
        for n, S in zip(static, Ss, strict=True):
            covs[n] = rot @ (0.5 * (S + S.T)) @ rot.T
    return covs


def _update(state, ids, zs, Rs, marks, skip, max_nis, gate_probability, nis=None, history=None,
            between=None, joint: bool = False) -> dict:
    """Gated updates: static points jointly, then the articulated landmarks, each with its R (one by one, or
    with ``joint`` in one update: ``ASlamParams.articulated_update``); j → accepted.

    ``Rs`` (k, 3, 3) are the observations' noise covariances. Motion is
    relative: when at least half of the frame's landmarks decided static (and
    at least two) fail the gate, and one correction of the robot explains them
    together, the robot estimate is off, not they, and they are used without
    the gate (as the oracle uses them). ``nis`` (j → NIS against this state), if given, holds the
    static points' NIS already computed (:func:`stslam.slam.onsets.onsets`). ``history``
    (:class:`~stslam.slam.replay.ReplayHistory`), if given, records the updates made; ``between()``, if
    given, is called after the static points' update and before the articulated landmarks'.
    """
    outcome = {}
    static = [j for j, i in enumerate(ids)
              if i in state and j not in skip and marks[i].status not in ARTICULATED]
    if static:
        static_ids = [ids[j] for j in static]
        # The χ² gate on each point's own NIS, computed once against the state before the update.
        values = (np.array([nis[j] for j in static]) if nis is not None
                  else state.observation_nis(static_ids, zs[static], Rs[static]))
        accepted = values <= max_nis
        decided = np.array([marks[i].status == "static" for i in static_ids])
        if decided.sum() >= 2 and 2 * np.sum(~accepted[decided]) >= decided.sum():
            # Consensus check: after a trial update with all of them, those that now fit are used
            # ungated (a landmark that still does not fit has moved), provided one correction of the
            # robot explains them together: their NIS after it, summed, passes the gate's χ² test
            # with 3 dof per point. Otherwise they disagree: some of them move (a drawer called
            # static while it rested), and the trial was pulled by them.
            rows = np.asarray(static)[decided]
            trial = state.copy()
            trial.update_landmarks([ids[j] for j in rows], zs[rows], Rs[rows])
            after = trial.observation_nis([ids[j] for j in rows], zs[rows], Rs[rows])
            if after.sum() <= chi2.ppf(gate_probability, 3 * rows.size):  # max_nis is its 3-dof quantile
                accepted[decided] |= after <= max_nis
        used = [j for j, ok in zip(static, accepted, strict=True) if ok]
        if used:
            state.update_landmarks([ids[j] for j in used], zs[used], Rs[used])
            if history is not None:
                history.record("joint", [ids[j] for j in used], zs[used], Rs[used])
        outcome.update(zip(static, accepted.tolist()))
    if between is not None:
        between()
    rows = [j for j, i in enumerate(ids) if i in state and j not in skip and marks[i].status in ARTICULATED]
    if rows:  # each gated on its own: one by one (SlamState.update_each) or against one state (joint)
        R_rows = np.array([marks[ids[j]].r_scale * Rs[j] for j in rows])
        if joint:  # each gated against the state the static points left, the accepted ones together
            accepted = state.update_landmarks([ids[j] for j in rows], zs[rows], R_rows, max_nis)[0]
        else:
            accepted = state.update_each([ids[j] for j in rows], zs[rows], R_rows, max_nis)
        outcome.update(zip(rows, accepted.tolist()))
        if history is not None:
            history.record("joint" if joint else "each", [ids[j] for j, ok in zip(rows, accepted) if ok],
                           zs[rows][accepted], R_rows[accepted])
    return outcome


def _report(mark: LandmarkMark) -> LandmarkReport:
    names = mark.selector.names
    mu = np.array(mark.mu_rows).reshape(-1, len(names))
    return LandmarkReport(mark.model, tuple(mark.decisions), mark.restarts, mark.rebases,
                          mark.selector_failures, np.array(mark.mu_frames, dtype=int), mu, names, mark.revisions)
