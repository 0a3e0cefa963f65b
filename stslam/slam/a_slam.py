"""A-SLAM: EKF SLAM whose landmarks take the articulation model selection chose for them (SPEC 6.3).

The shared core (:class:`~stslam.slam.core.SlamState`, one EKF for
everything) plus a policy per landmark, written for the two traps of SPEC 6.3.
Settings: :class:`~stslam.slam.a_slam_settings.ASlamParams`.

1. **From first sight** (trap (a)) a landmark is a static point (random walk
   ``sigma_walk``) whose observations must pass a χ² gate (3 dof), exactly as
   in ``ekf_slam_gated``: before any decision A-SLAM *is* the gated EKF.
2. **Selection** (SPEC 4). Each observation, mapped to the world with the
   frame's posterior pose, m = R(θ̂) z + [x̂, ŷ, 0]ᵀ (SPEC 5.2), goes to the
   landmark's :class:`~stslam.selection.ModelSelector` with the time since
   the previous one — but only when the pose uncertainty moves m by at most
   ``max_pose_sigma_m`` (std of J_pose P_pose J_poseᵀ): the points inherit the
   pose error, which is slowly varying, so an uncertain robot would make
   static points look articulated. A decision is the selector's current
   model held for ``hold_steps`` consecutive observations.
3. **Conversion.** Static: the point stays and its selector stops. Prismatic
   or revolute: at the next sighting, before that frame's update, the static
   point is replaced by an :class:`~stslam.slam.blocks.ArticulatedBlock` on
   the selector's latest structure, initialised from that observation like a
   new landmark (q by inverse kinematics, cross-covariance to the robot), with
   the selector's rate estimates (covariance + ``sigma_rate0``²). The stale
   point is dropped, not converted: a moving landmark's observations were
   gated out, so it holds nothing of value.
4. **Refinement** (trap (b)). After each decision an articulated landmark's
   selector gets ``refine_until`` more observations; each structure refit on
   the growing window is carried into the state (:mod:`stslam.slam.rebase`,
   with its Jacobian), and it may switch to the other articulated model, never
   back to static (at rest it is a joint with zero rate). Its observations use
   R(1 + κ p/n) (p free structure parameters, n fitted points, κ
   ``structure_inflation``), the predictive variance of a least-squares fit
   (:mod:`stslam.model_bank`) widened because the structure error is the same
   at every step, not white: a crude early structure cannot pull the robot hard.
5. **Relative motion.** When half or more of a frame's decided-static
   landmarks fail the gate, the robot is off, not they: after a trial update
   with all of them, those that then fit are used ungated (as the oracle
   would). A decided landmark rejected ``restart_after`` times in a row while
   other observations pass has moved (a door at rest that opens) or was lost:
   it is re-initialised from the current, unused observation — a static one
   as an undecided point under the same selector, an articulated one on its
   model — and reviewed again.
"""

from __future__ import annotations

import copy
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from stslam import ekf
from stslam.articulation import get_model
from stslam.ekf import InnovationCovarianceError
from stslam.model_bank import STRUCTURE_DOF
from stslam.selection import ModelSelector
from stslam.sensor import point_from_observation
from stslam.simulate import SimulatedRun
from stslam.slam.a_slam_settings import ARTICULATED, ASlamParams, a_slam_params
from stslam.slam.blocks import ArticulatedBlock, StaticPointBlock
from stslam.slam.core import SlamState
from stslam.slam.rebase import rebase_motion_state

__all__ = ["ASlamParams", "ASlamTrack", "LandmarkReport", "a_slam_params", "run_a_slam", "selection_scores"]

@dataclass
class _Landmark:
    """Mutable per-run bookkeeping of one landmark (see :class:`LandmarkReport`)."""

    selector: ModelSelector
    status: str = "undecided"  # undecided | static | prismatic | revolute
    pending: str | None = None  # articulated model chosen, to be converted at the next sighting
    structure: object = None
    r_scale: float = 1.0  # R multiplier 1 + κ p/n of the current structure
    rejections: int = 0
    last_frame: int | None = None
    n_fed: int = 0  # observations fed to earlier selectors (before restarts)
    decisions: list = field(default_factory=list)  # (frame, step, model)
    restarts: int = 0
    rebases: int = 0
    selector_failures: int = 0
    refine_stopped: bool = False
    review_until: int = 0  # selector observation count up to which an articulated model is reviewed
    mu_frames: list = field(default_factory=list)
    mu_rows: list = field(default_factory=list)


@dataclass(frozen=True)
class LandmarkReport:
    """What A-SLAM did with one landmark.

    Attributes
    ----------
    model : str
        Model of its block at the end: ``undecided`` (still a gated static
        point), ``static``, ``prismatic`` or ``revolute``.
    decisions : tuple of (frame, step, model)
        Every decision: run frame, observation index of the landmark (0-based,
        counted from its first sighting across restarts) and chosen model.
    restarts, rebases, selector_failures : int
        Re-initialisations after repeated gate rejections; structure refits
        carried into the state; selectors replaced after a numerical failure.
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

def run_a_slam(params: ASlamParams, run: SimulatedRun, observer: Callable | None = None) -> ASlamTrack:
    """Run A-SLAM over a simulated sequence from the true first pose (as ``run_filter``).

    Frame k: predict (k ≥ 1, SPEC 5.1); convert landmarks whose articulated
    model was chosen since their last sighting (from this frame's
    observation); update with the other observations (gated; static points
    jointly, articulated ones each with its own R); restart decided landmarks
    rejected ``restart_after`` times in a row; add new landmarks as static
    points; feed the selectors. ``observer(k, state)``, if given, is called
    after each frame.
    """
    world = run.world
    n = world.n_frames
    R = run.sensor.R
    static_block = StaticPointBlock(params.sigma_walk)
    state = SlamState(world.poses_xytheta[0], np.zeros((3, 3)))
    marks: dict[int, _Landmark] = {}
    poses, covs = np.empty((n, 3)), np.empty((n, 3, 3))
    rejected = 0
    for k in range(n):
        if k > 0:
            state.predict(run.controls_odometry[k - 1], run.control_cov(k - 1), world.dt)
        ids = [int(i) for i in run.observation_ids[k]]
        zs = run.observations[k]
        initialised = set()
        for j, i in enumerate(ids):
            if i in marks and marks[i].pending is not None:
                _convert(state, i, marks[i], zs[j], R, params)
                initialised.add(j)
        outcome = _update(state, ids, zs, marks, initialised, R, params.max_nis)
        n_accepted = sum(outcome.values())
        rejected += len(outcome) - n_accepted
        for j, ok in outcome.items():
            mark = marks[ids[j]]
            # A rejection counts against a decided landmark only while other observations of the
            # frame pass: when all fail, the robot is off, not the landmark.
            if ok or mark.status == "undecided" or n_accepted == 0:
                mark.rejections = 0
            else:
                mark.rejections += 1
            if mark.rejections >= params.restart_after:
                _restart(state, ids[j], mark, zs[j], R, static_block, params)
        for j, i in enumerate(ids):
            if i not in state:
                state.add_landmark(i, static_block, zs[j], R)
                marks[i] = _Landmark(ModelSelector(params.selection))
        pose, pose_cov = state.pose, state.pose_cov
        for j, i in enumerate(ids):
            m, dm_dpose, _ = point_from_observation(pose, zs[j])
            # Selection sees only points whose pose-induced error is small (module docstring).
            if np.linalg.eigvalsh(dm_dpose @ pose_cov @ dm_dpose.T)[-1] <= params.max_pose_sigma_m ** 2:
                _select(state, i, marks[i], m, k, world.dt, params)
        poses[k], covs[k] = state.pose, state.pose_cov
        if observer is not None:
            observer(k, state)
    return ASlamTrack(poses, covs, rejected, {i: _report(m) for i, m in sorted(marks.items())})


def _update(state, ids, zs, marks, skip, R, max_nis) -> dict:
    """Gated updates: static points jointly, then each articulated landmark with its R; j → accepted.

    Motion is relative: when at least half of the frame's landmarks decided
    static (and at least two) fail the gate, the robot estimate is off, not
    they, and they are used without the gate (as the oracle uses them).
    """
    outcome = {}
    static = [j for j, i in enumerate(ids)
              if i in state and j not in skip and marks[i].status not in ARTICULATED]
    if static:
        bounds = [max_nis] * len(static)
        decided = [r for r, j in enumerate(static) if marks[ids[j]].status == "static"]
        if len(decided) >= 2:
            failing = sum(_nis(state, ids[static[r]], zs[static[r]], R) > max_nis for r in decided)
            if 2 * failing >= len(decided):
                # Consensus check: after a trial update with all of them, those that now fit
                # are used ungated; a landmark that still does not fit has moved.
                trial = copy.copy(state)
                trial.update_landmarks([ids[static[r]] for r in decided], zs[[static[r] for r in decided]], R)
                for r in decided:
                    if _nis(trial, ids[static[r]], zs[static[r]], R) <= max_nis:
                        bounds[r] = None
        accepted, _ = state.update_landmarks([ids[j] for j in static], zs[static], R, bounds)
        outcome.update(zip(static, accepted.tolist()))
    for j, i in enumerate(ids):
        if i in state and j not in skip and marks[i].status in ARTICULATED:
            outcome[j] = bool(state.update_landmark(i, zs[j], marks[i].r_scale * R, max_nis).accepted)
    return outcome


def _nis(state: SlamState, landmark_id, z_robot, R) -> float:
    """Normalised innovation squared yᵀS⁻¹y of one observation against the current state."""
    z_hat, cols, H_cols = state.predict_observation(landmark_id)
    S, _ = ekf.innovation_covariance_sparse(state.P, cols, H_cols, R)
    return ekf.innovation_stats(np.asarray(z_robot, dtype=float) - z_hat, S)[0]


def _articulated_block(model_name: str, structure, params: ASlamParams) -> ArticulatedBlock:
    return ArticulatedBlock(get_model(model_name), structure, params.selection.filters[model_name].order,
                            params.sigma_eta(model_name), params.sigma_rate0(model_name))


def _structure_scale(mark: _Landmark, model_name: str, params: ASlamParams) -> float:
    """R multiplier max(1, ρ²/σ²)(1 + κ p/n) for the structure the selector fitted on n points.

    ρ is the fit's RMS residual (m): a structure that misses its own window by
    more than the sensor noise (a line through an arc) cannot predict better.
    """
    model_filter = mark.selector.filters[mark.selector.names.index(model_name)]
    sigma = params.selection.measurement_sigma_m
    misfit = max(1.0, (model_filter.structure.residual_m / sigma) ** 2)
    return misfit * (1.0 + params.structure_inflation * STRUCTURE_DOF[model_name] / max(model_filter.n_fit, 1))


def _convert(state: SlamState, landmark_id, mark: _Landmark, z_robot, R, params: ASlamParams,
             selector_rates: bool = True) -> None:
    """Give the landmark the chosen model's block, initialised from observation z (SPEC 6.3).

    q comes from z (inverse kinematics of m = R(θ)z + t, with the
    cross-covariance to the robot); the rates from the selector's filter on the
    same structure (``selector_rates``) or zero, each with ``sigma_rate0``² added.
    """
    name, mark.pending = mark.pending, None
    structure = mark.selector.structure(name)
    block = _articulated_block(name, structure, params)
    state.remove_landmark(landmark_id)
    state.add_landmark(landmark_id, block, z_robot, R)  # q = IK(m), rates 0 with σ_rate0² prior
    if selector_rates:
        # x_b ← [q, rates], J = diag(1, 0, …) keeps q and its correlations, extra = rate covariance.
        model_filter = mark.selector.filters[mark.selector.names.index(name)]
        idx = state.indices(landmark_id)
        x_b = state.x[idx].copy()
        dof = block.dof
        x_b[dof:] = model_filter.x[dof:]
        J = np.zeros((idx.size, idx.size))
        J[:dof, :dof] = np.eye(dof)
        extra = np.zeros_like(J)
        extra[dof:, dof:] = model_filter.P[dof:, dof:] + params.sigma_rate0(name) ** 2 * np.eye(idx.size - dof)
        state.replace_block(landmark_id, block, x_b, J, extra)
    mark.status, mark.structure = name, structure
    mark.r_scale = _structure_scale(mark, name, params)


def _rebase(state: SlamState, landmark_id, mark: _Landmark, name: str, params: ASlamParams) -> None:
    """Carry the motion state onto the selector's latest structure of model ``name`` (SPEC 6.3(b))."""
    structure = mark.selector.structure(name)
    idx = state.indices(landmark_id)
    x_new, J = rebase_motion_state(mark.structure, structure, state.x[idx])
    state.replace_block(landmark_id, _articulated_block(name, structure, params), x_new, J,
                        np.zeros((idx.size, idx.size)))
    mark.status, mark.structure = name, structure
    mark.r_scale = _structure_scale(mark, name, params)
    mark.rebases += 1


def _to_static(state: SlamState, landmark_id, mark: _Landmark, params: ASlamParams) -> None:
    """Articulated → static point: m = f(C, q), J = ∂m/∂X = [∂f/∂q, 0, …] (SPEC 2)."""
    idx = state.indices(landmark_id)
    m, dm_dx = state.block(landmark_id).position(state.x[idx])
    state.replace_block(landmark_id, StaticPointBlock(params.sigma_walk), m, dm_dx, np.zeros((3, 3)))
    mark.structure, mark.r_scale = None, 1.0


def _restart(state, landmark_id, mark: _Landmark, z_robot, R, static_block, params: ASlamParams) -> None:
    """A decided landmark failed the gate ``restart_after`` times while others passed: it moved, or was lost.

    Static: the point is re-initialised from z and goes back under selection
    (the same selector, which keeps its history). Articulated: its motion state
    is re-initialised from z on the same model (rates from the selector while
    it is fed, else zero) and its review is reopened.
    """
    if mark.status == "static":
        state.remove_landmark(landmark_id)
        state.add_landmark(landmark_id, static_block, z_robot, R)
        mark.status = "undecided"
    else:
        reviewing = mark.selector.n_observations < mark.review_until and not mark.refine_stopped
        mark.pending = mark.status
        _convert(state, landmark_id, mark, z_robot, R, params, selector_rates=reviewing)
        mark.review_until = mark.selector.n_observations + params.refine_until
        mark.refine_stopped = False
    mark.rejections = 0
    mark.restarts += 1


def _select(state, landmark_id, mark: _Landmark, m_world, k: int, dt: float, params: ASlamParams) -> None:
    """Feed one world-frame point to the landmark's selector; act on a held decision or a refit.

    A decision is the selector's current model (μ_j > τ, SPEC 4, and its
    decision gates) at ``hold_steps`` consecutive observations. Undecided landmarks are fed until they
    are decided; a landmark decided static is no longer fed (until a restart);
    an articulated one is fed for ``refine_until`` more observations after each
    decision or restart, during which its structure is refined and it may
    switch to the other model; back to static only if it has not been seen
    moving (moved less than ``moved_m`` from where it started): a door at rest
    is a joint with zero rate, not a static point.
    """
    reviewing = (mark.status in ARTICULATED and not mark.refine_stopped
                 and mark.selector.n_observations < mark.review_until)
    if not (mark.status == "undecided" or reviewing):
        return
    gap = None if mark.last_frame is None else (k - mark.last_frame) * dt
    try:
        mu = mark.selector.observe(m_world, gap)
    except InnovationCovarianceError:
        # A model's filter broke down (e.g. a near-infinite circle fitted to a line, predicted
        # across a long gap). Under review: keep the model in use. Undecided: start over here.
        mark.selector_failures += 1
        if reviewing:
            mark.refine_stopped = True
            return
        mark.n_fed += mark.selector.n_observations
        mark.selector = ModelSelector(params.selection)
        mu = mark.selector.observe(m_world, None)
    mark.last_frame = k
    mark.mu_frames.append(k)
    names = mark.selector.names
    mark.mu_rows.append(np.full(len(names), np.nan) if mu is None else mu)
    # The selector's own decision per observation (μ_j > τ and its decision gates), held for
    # ``hold_steps`` consecutive observations.
    recent = mark.selector.current_history[-params.selection.hold_steps:]
    best = recent[-1] if len(recent) == params.selection.hold_steps and len(set(recent)) == 1 else None
    current = mark.pending or mark.status
    seen_moving = mark.selector.moved_m > params.moved_m
    if best is not None and best != current and not (seen_moving and best == "static"):
        mark.decisions.append((k, mark.n_fed + mark.selector.n_observations - 1, best))
        if best == "static":
            if mark.status in ARTICULATED:
                _to_static(state, landmark_id, mark, params)
            mark.status, mark.pending = "static", None
        elif mark.status in ARTICULATED:
            _rebase(state, landmark_id, mark, best, params)
        else:
            mark.pending = best
        if best in ARTICULATED:
            mark.review_until = mark.selector.n_observations + params.refine_until
    elif mark.status in ARTICULATED and mark.selector.structure(mark.status) is not mark.structure:
        _rebase(state, landmark_id, mark, mark.status, params)


def _report(mark: _Landmark) -> LandmarkReport:
    names = mark.selector.names
    mu = np.array(mark.mu_rows).reshape(-1, len(names))
    return LandmarkReport(mark.pending or mark.status, tuple(mark.decisions), mark.restarts, mark.rebases,
                          mark.selector_failures, np.array(mark.mu_frames, dtype=int), mu, names)


# ---------------------------------------------------------------------- scores

def selection_scores(track: ASlamTrack, world) -> dict:
    """Per-run selection metrics of A-SLAM against the world's true models (SPEC 4, 12).

    Returns
    -------
    dict
        ``correct``: 1 when every moving landmark ends with its true model,
        else 0; ``moving_correct_frac``: the fraction of moving landmarks that
        do; ``selection_step``: the largest, over moving landmarks, of the
        observation index at which their true model was first chosen (NaN if
        one never was); ``static_correct_frac``: fraction of the static
        landmarks with a decision whose final model is static (NaN if none).
    """
    hits_moving, steps, static_hits, static_decided = [], [], 0, 0
    for i, truth in enumerate(world.landmarks):
        report = track.landmarks.get(i)
        model = report.model if report is not None else "undecided"
        if truth.model_name == "static":
            if model != "undecided":
                static_decided += 1
                static_hits += model == "static"
            continue
        hits_moving.append(model == truth.model_name)
        hits = [step for _, step, chosen in (report.decisions if report else ()) if chosen == truth.model_name]
        steps.append(hits[0] if hits else np.nan)
    return {"correct": int(all(hits_moving)),
            "moving_correct_frac": float(np.mean(hits_moving)) if hits_moving else np.nan,
            "selection_step": float(np.max(steps)) if steps else np.nan,
            "static_correct_frac": static_hits / static_decided if static_decided else np.nan}
