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

from stslam.robot.sensor import point_from_observation, pose_induced_variance, world_point_covariances
from stslam.geometry import rotation_z
from stslam.slam.bodies.policy import BodyLandmarkPolicy
from stslam.slam.bodies.state import BodySlamState
from stslam.slam.landmark_policy import LandmarkMark, LandmarkPolicy
from stslam.slam.a_slam_settings import ARTICULATED, ASlamParams
from stslam.slam.blocks import StaticPointBlock
from stslam.slam.core import SlamState
from stslam.slam.inputs import as_inputs
from stslam.slam.loop import Frame, run_slam

__all__ = ["ASlamFramePolicy", "ASlamParams", "ASlamTrack", "LandmarkReport", "run_a_slam"]

DRIFT_FLOOR_M = 0.002  # a static estimate's change below this (m) is no evidence of motion (_drifted)


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

    def __init__(self, params: ASlamParams, inputs):
        inputs = as_inputs(inputs)
        step_s = float(np.median(inputs.dts_s)) if inputs.n_frames > 1 else 1.0
        self.params = replace(params, selection=params.selection.with_dt(params.classify_every * step_s))
        # SPEC 13: with ``bodies``, landmarks moving rigidly together share one motion state.
        self.landmarks = (LandmarkPolicy if params.bodies is None else BodyLandmarkPolicy)(self.params)
        self.times_s = inputs.times_s
        sigma = self.params.max_pose_sigma_m
        self.max_nis, self.max_pose_var = self.params.max_nis, np.inf if sigma is None else sigma ** 2

    def before_update(self, state: SlamState, frame: Frame) -> set:
        """Convert pending landmarks from this frame's observation; the indices j so used."""
        marks = self.landmarks.marks
        return {j for j, i in enumerate(frame.ids)
                if i in marks and marks[i].pending is not None
                and self.landmarks.convert(state, i, frame.zs[j], frame.Rs[j])}

    def update(self, state: SlamState, frame: Frame, skip: set) -> dict:
        held, nis = _onsets(state, frame, self.landmarks.marks, skip, self.params, float(self.times_s[frame.k]))
        outcome = _update(state, frame.ids, frame.zs, frame.Rs, self.landmarks.marks, skip | set(held),
                          self.max_nis, self.params.gate_probability, nis)
        # a held-out point the gate would reject counts as rejected (its restarts re-place it); one the gate
        # would pass is left out of the count (a false alarm must not re-place a well-mapped point)
        outcome.update({j: False for j, passed in held.items() if not passed})
        return outcome

    def after_update(self, state: SlamState, frame: Frame, outcome: dict) -> None:
        """Count rejections of decided landmarks; restart those rejected ``restart_after`` times in a row."""
        n_accepted = sum(outcome.values())
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

    def add_landmark(self, state: SlamState, landmark_id: int, z_robot, R) -> None:
        """A new landmark is an undecided static point."""
        state.add_landmark(landmark_id, self.landmarks.static_block, z_robot, R)
        self.landmarks.new_mark(landmark_id)

    def after_frame(self, state: SlamState, frame: Frame) -> None:
        """Feed the selectors with the frame's points mapped to the world by the posterior pose (SPEC 5.2)."""
        policy, ids, zs = self.landmarks, frame.ids, frame.zs
        wanted = [j for j, i in enumerate(ids) if policy.wants(policy.marks[i])]
        if wanted and self.max_pose_var != np.inf:
            # Selection sees only points whose pose-induced error is small (landmark_policy docstring).
            near = pose_induced_variance(state.pose, state.pose_cov, zs[wanted]) <= self.max_pose_var
            wanted = [j for j, ok in zip(wanted, near, strict=True) if ok]
        covs = selection_covariances(state, frame, wanted, self.params.selection_covariance)
        for j, cov in zip(wanted, covs, strict=True):
            policy.select(state, ids[j], point_from_observation(state.pose, zs[j])[0], frame.k, self.times_s, cov)
        if self.params.bodies is not None:
            policy.group(state, frame)

    def new_state(self, pose_xytheta, pose_cov, motion_order: int, update_iterations: int) -> SlamState:
        """The EKF state of a run: one whose members may share a founder's block when ``bodies`` is set."""
        make = SlamState if self.params.bodies is None else BodySlamState
        return make(pose_xytheta, pose_cov, motion_order, update_iterations)

    def track(self, poses_xytheta, pose_covs, n_rejected: int) -> ASlamTrack:
        reports = {i: _report(m) for i, m in sorted(self.landmarks.marks.items())}
        return ASlamTrack(poses_xytheta, pose_covs, n_rejected, reports)


def run_a_slam(params: ASlamParams, inputs, observer: Callable | None = None,
               motion_order: int = 2, update_iterations: int = 1) -> ASlamTrack:
    """Run A-SLAM over one sequence (:class:`~stslam.slam.inputs.SlamInputs` or a SimulatedRun) from its first pose.

    :func:`stslam.slam.loop.run_slam` with an :class:`ASlamFramePolicy`;
    ``observer(k, state)``, if given, is called after each frame; ``motion_order`` and
    ``update_iterations`` as in :class:`~stslam.slam.core.SlamState`.
    """
    inputs = as_inputs(inputs)
    return run_slam(inputs, ASlamFramePolicy(params, inputs), motion_order, update_iterations, observer)


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


def _onsets(state, frame: Frame, marks, skip, params: ASlamParams, t: float = 0.0) -> tuple[dict, dict | None]:
    """Static points that have begun to move (held out of this frame's update), and every static NIS.

    A CUSUM of each static point's NIS against its own estimate (3 dof, mean 3),
    g ← max(0, g + NIS − ``onset_allowance``), finds a slow start (a drawer's first
    steps each pass the χ² gate, and a point used while it slides drags the robot:
    in the kitchen this, not the models, was most of A-SLAM's NEES excess). Above
    ``onset_threshold`` the point is a suspect, held out until its NIS has stayed
    under the allowance for ``onset_quiet`` frames in a row (it rests again). Returns
    (j → whether the held-out observation would have passed the gate, j → its NIS for every
    static row j: the gate of :func:`_update` reads the same values). ``t``: the frame's time (:func:`_drifted`).
    """
    if params.onset_allowance is None:
        return {}, None
    rows = [j for j, i in enumerate(frame.ids)
            if i in state and j not in skip and marks[i].status not in ARTICULATED]
    if not rows:
        return {}, None
    nis = state.observation_nis([frame.ids[j] for j in rows], frame.zs[rows], frame.Rs[rows])
    # The allowance grows with the frame's NIS: when even its best-fitting points have a high NIS, the
    # robot is off (or the filter's covariance too small), and that is no point's motion (settings docstring).
    values = nis.tolist()
    allowance = max(params.onset_allowance, 2.0 * _quantile(values, params.onset_frame_quantile))
    held = {}
    # The drift test reads a filter's estimates (a smoother revises its past ones): EKF states only.
    drift_bound = params.drift_bound if isinstance(state, SlamState) else None
    shifts = _innovations(state, frame, rows) if params.onset_windows and isinstance(state, SlamState) else None
    for i in frame.ids:  # an anchor (and an innovation window) belongs to one static life of a point
        if i in marks and marks[i].status in ARTICULATED:
            marks[i].anchor, marks[i].window = None, []
    for n, (j, value) in enumerate(zip(rows, values, strict=True)):
        mark = marks[frame.ids[j]]
        mark.onset = max(0.0, mark.onset + value - allowance)
        if mark.suspect:
            mark.quiet = mark.quiet + 1 if value <= allowance else 0
            mark.suspect = mark.quiet < params.onset_quiet
        elif mark.onset > params.onset_threshold or (
                drift_bound is not None and _drifted(state, frame.ids[j], mark, drift_bound, t, params.sigma_walk)) or (
                shifts is not None and _shifted(mark, shifts[0][n], shifts[1][n], params)):
            mark.suspect, mark.quiet, mark.anchor, mark.window = True, 0, None, []  # re-anchored where it rests again
        if mark.suspect:
            mark.onset = 0.0
            held[j] = value <= params.max_nis  # True: within the gate, held out without counting against it
    return held, dict(zip(rows, values, strict=True))


def _quantile(values: list, q: float) -> float:
    """The q-quantile of ``values`` interpolated linearly between order statistics (numpy's default; at
    q = 0.5 exactly ``statistics.median``), in Python: 70x faster than numpy on a frame's few dozen."""
    ordered = sorted(values)
    position = q * (len(ordered) - 1)
    low = int(position)
    if low + 1 >= len(ordered):
        return ordered[-1]
    frac = position - low
    return (1.0 - frac) * ordered[low] + frac * ordered[low + 1]


def _drifted(state, landmark_id, mark: LandmarkMark, bound: float, t: float, sigma_walk: float) -> bool:
    """Whether a static point's estimate m has left its anchor (m_a, P_a) by more than refinement explains.

    For a constant estimated by a linear filter, the change of the estimate between two times is
    independent of the later error, so m − m_a ~ N(0, P_a − P) while the point stays put (SPEC 6.3's
    static point; the filter's marginals m, P of :meth:`landmark_position`); its random walk (SPEC 6.3 (a),
    ``sigma_walk``) may move it by σ_walk²(t − t_a) I more. The statistic (m − m_a)ᵀC⁻¹(m − m_a), C the sum of
    the two, is compared with ``bound`` (a χ² quantile, 3 dof); C is floored at (``DRIFT_FLOOR_M``)² per
    direction. The anchor is set at the first test of a static life and moves to
    the current estimate whenever the point's variance has halved since, so the reference sharpens as
    the point is refined. Catches a point the filter follows as it moves (a young point, whose large
    gain keeps the innovations, hence the NIS CUSUM, small).
    """
    m, P = state.landmark_position(landmark_id)
    if mark.anchor is None:
        mark.anchor = (m, P, t)
        return False
    m_a, P_a, t_a = mark.anchor
    values, vectors = np.linalg.eigh(0.5 * ((P_a - P) + (P_a - P).T))
    d = vectors.T @ (m - m_a)
    walked = sigma_walk ** 2 * (t - t_a)
    if float(np.sum(d ** 2 / np.maximum(values + walked, DRIFT_FLOOR_M ** 2))) > bound:
        return True
    if np.trace(P) < 0.5 * np.trace(P_a):
        mark.anchor = (m, P, t)
    return False


def _innovations(state: SlamState, frame: Frame, rows: list) -> tuple[np.ndarray, np.ndarray]:
    """World-axis innovations ν (k, 3) and their covariances S (k, 3, 3) of the static ``rows`` of ``frame``
    against the state before its update (SPEC 5.3: y = z − h(x), S = H P Hᵀ + R, turned by R(θ))."""
    ids = [frame.ids[j] for j in rows]
    rot = rotation_z(state.pose[2])
    y = frame.zs[rows] - np.array([state.predict_observation(i)[0] for i in ids])
    S = np.array(state.innovation_covariances(ids, frame.Rs[rows]))
    return y @ rot.T, rot @ S @ rot.T


def _shifted(mark: LandmarkMark, y, S, params: ASlamParams) -> bool:
    """Whether a static point's recent innovations share a mean: a windowed GLR test of a shift.

    While a point stays put (SPEC 6.3's static point), a consistent filter's innovations are white,
    y_k ~ N(0, S_k): over the last w sightings (Σy)ᵀ(ΣS)⁻¹(Σy) ~ χ²₃. A point that moved and rests elsewhere,
    or whose estimate averaged a stretch of motion, leaves a mean b in every innovation: non-centrality
    w bᵀS⁻¹b grows with w although each NIS stays small (the CUSUM's allowance hides a bias under ~2σ).
    Each window length w of ``onset_windows`` is tested against ``window_bound`` (χ²₃ at
    1 − (1 − ``onset_window_probability``)/#windows: Bonferroni over the lengths). The window holds one
    static life (cleared at a flag, a restart, a conversion).
    """
    mark.window = (mark.window + [(y, S)])[-max(params.onset_windows):]
    sum_y, sum_S = np.zeros(3), np.zeros((3, 3))
    n = 0
    for w in sorted(params.onset_windows):
        if w > len(mark.window):
            break
        for y_k, S_k in mark.window[len(mark.window) - w:len(mark.window) - n]:
            sum_y += y_k
            sum_S += S_k
        n = w
        if float(sum_y @ np.linalg.solve(sum_S, sum_y)) > params.window_bound:
            return True
    return False


def _update(state, ids, zs, Rs, marks, skip, max_nis, gate_probability, nis=None) -> dict:
    """Gated updates: static points jointly, then each articulated landmark with its R; j → accepted.

    ``Rs`` (k, 3, 3) are the observations' noise covariances. Motion is
    relative: when at least half of the frame's landmarks decided static (and
    at least two) fail the gate, and one correction of the robot explains them
    together, the robot estimate is off, not they, and they are used without
    the gate (as the oracle uses them). ``nis`` (j → NIS against this state), if given, holds the
    static points' NIS already computed (:func:`_onsets`).
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
        outcome.update(zip(static, accepted.tolist()))
    rows = [j for j, i in enumerate(ids) if i in state and j not in skip and marks[i].status in ARTICULATED]
    if rows:  # each gated on its own (SlamState.update_each)
        R_rows = np.array([marks[ids[j]].r_scale * Rs[j] for j in rows])
        outcome.update(zip(rows, state.update_each([ids[j] for j in rows], zs[rows], R_rows, max_nis).tolist()))
    return outcome


def _report(mark: LandmarkMark) -> LandmarkReport:
    names = mark.selector.names
    mu = np.array(mark.mu_rows).reshape(-1, len(names))
    return LandmarkReport(mark.model, tuple(mark.decisions), mark.restarts, mark.rebases,
                          mark.selector_failures, np.array(mark.mu_frames, dtype=int), mu, names, mark.revisions)
