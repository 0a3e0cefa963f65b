"""A-SLAM's rule per landmark: selection, conversion, refinement, restarts (SPEC 4, 6.3).

A-SLAM's frame hooks (:class:`stslam.slam.a_slam.ASlamFramePolicy`, run by
:func:`stslam.slam.loop.run_slam`) call a :class:`LandmarkPolicy`, which keeps
one :class:`LandmarkMark` per landmark and changes that landmark's block in
the shared :class:`~stslam.slam.core.SlamState`.
Settings: :class:`~stslam.slam.a_slam_settings.ASlamParams`.

* **Selection** (SPEC 4). Every ``classify_every``-th observation, mapped to
  the world with the frame's posterior pose, m = R(θ̂) z + [x̂, ŷ, 0]ᵀ
  (SPEC 5.2), goes to the landmark's :class:`~stslam.selection.selector.ModelSelector`
  with the time since the previous one and its covariance
  (``selection_covariance``, :func:`stslam.slam.a_slam.selection_covariances`, SPEC 13): the points
  inherit the pose error, and against σ_z alone an uncertain robot would make static points look
  articulated. An optional hard bound, ``max_pose_sigma_m``, withholds the points whose pose-induced
  std exceeds it. A decision is the selector's current model held for ``hold_steps`` consecutive observations.
* **Conversion.** Static: the point stays and its selector is fed on: a
  part called static while it rested is converted once it is seen moving
  (decisions are revisable, SPEC 16; each point's covariance keeps the pose's wander from counting
  as motion). An articulated model of ``convert``: at the next sighting, before that frame's update,
  the static point is replaced by an
  :class:`~stslam.slam.blocks.ArticulatedBlock` on the selector's latest
  structure (with ``common_axis``: the landmark's circle about the hinge axis
  fitted jointly on every landmark held revolute, :mod:`stslam.articulation.hinge_axis`;
  the conversion waits until that axis exists), initialised from that
  observation like a new landmark, with the selector's rate estimates
  (covariance + ``sigma_rate0``²). The stale point is dropped: a moving
  landmark's observations were gated out. A decision for an articulated model
  not in ``convert`` is only recorded: the landmark stays a gated static point
  and its selector is fed on.
* **Refinement** (SPEC 6.3(b)). After each decision an articulated landmark's
  selector gets ``refine_until`` more observations; each structure refit is
  carried into the state (:mod:`stslam.articulation.rebase`, with its Jacobian), and
  it may switch to the other articulated model, never back to static once seen
  moving (a door at rest is a joint with zero rate). Its observations use
  R · max(1, ρ²/σ²)(1 + κ p/n): ρ the fit's RMS residual, p free structure
  parameters, n fitted points, κ ``structure_inflation`` — the structure error
  is the same at every step, not white, so a crude early structure cannot
  pull the robot hard. With ``structure_state`` corrected or consider (EKF states only) the
  block carries its structure's correction δ (SPEC 6.3(b);
  :class:`~stslam.slam.blocks.CorrectedArticulatedBlock`), updated or a consider parameter;
  what each does to refits and κ: :class:`~stslam.slam.a_slam_settings.ASlamParams`.
* **Restart.** A decided landmark rejected ``restart_after`` times in a row while others pass is
  re-initialised from the current observation and reviewed again. Revisions: :mod:`stslam.slam.bodies.decisions`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stslam.articulation.correction import fit_correction_covariance
from stslam.articulation.models import get_model
from stslam.kalman.ekf import InnovationCovarianceError
from stslam.errors import DegenerateFitError
from stslam.articulation.hinge_axis import circle_on_axis, estimate_hinge_axis
from stslam.selection.model_filter import STRUCTURE_DOF
from stslam.selection.selector import ModelSelector
from stslam.slam.a_slam_settings import ARTICULATED, ASlamParams
from stslam.slam.blocks import ArticulatedBlock, CorrectedArticulatedBlock, StaticPointBlock
from stslam.slam.bodies.decisions import selector_action
from stslam.slam.core import SlamState
from stslam.articulation.rebase import rebase_motion_state


@dataclass
class LandmarkMark:
    """Mutable per-run bookkeeping of one landmark (see :class:`stslam.slam.a_slam.LandmarkReport`)."""

    selector: ModelSelector
    status: str = "undecided"  # undecided | static | prismatic | revolute (the block in the state)
    pending: str | None = None  # articulated model chosen, to be converted at the next sighting
    held: str | None = None  # articulated model decided but not in ``convert`` (recorded only)
    structure: object = None  # structure of the articulated block
    fitted: object = None  # the selector's structure it was derived from
    r_scale: float = 1.0  # R multiplier of the current structure
    fixed_scale: float = 1.0  # ... were the structure held fixed (a body member's, which is)
    rejections: int = 0
    onset: float = 0.0  # CUSUM of its static NIS (stslam.slam.onsets.onsets)
    rising: int | None = None  # frame at which that CUSUM last left zero (None: at zero)
    flagged: int | None = None  # frame at which it last became a suspect
    suspect: bool = False  # a static point that began to move: held out until it rests again ...
    quiet: int = 0  # ... for this many frames in a row
    anchor: tuple | None = None  # (m_a, P_a, t_a) of its static estimate (stslam.slam.onsets.drifted)
    window: list = field(default_factory=list)  # its latest static innovations (y, S) (stslam.slam.onsets.shifted)
    last_frame: int | None = None
    n_seen: int = 0  # sightings (for ``classify_every``)
    n_fed: int = 0  # observations fed to earlier selectors (before restarts)
    decisions: list = field(default_factory=list)  # (frame, step, model)
    restarts: int = 0
    rebases: int = 0
    revisions: int = 0  # model switches made by the window evidence (stslam.slam.bodies.decisions)
    selector_failures: int = 0
    refine_stopped: bool = False
    review_until: int = 0  # selector observation count up to which an articulated model is reviewed
    mu_frames: list = field(default_factory=list)
    mu_rows: list = field(default_factory=list)
    body: object = None  # founder id of the body it is a member of (stslam.slam.bodies), None otherwise

    @property
    def model(self) -> str:
        """The landmark's model: pending conversion, else a recorded decision while undecided, else its block's."""
        if self.pending is not None:
            return self.pending
        if self.status == "undecided" and self.held is not None:
            return self.held
        return self.status


class LandmarkPolicy:
    """The per-landmark rule of A-SLAM (module docstring); ``marks`` maps landmark id → :class:`LandmarkMark`."""

    def __init__(self, params: ASlamParams):
        self.params = params
        self.static_block = StaticPointBlock(params.sigma_walk)
        self.marks: dict[int, LandmarkMark] = {}
        self._axis_cache = (None, None)  # (ids the common axis was fitted on, HingeAxis or None)
        self._final_fits: dict = {}  # id -> (selector, its observation count, final revolute structure)
        self.revises = False  # whether window evidence, not the selector, switches articulated models

    def new_mark(self, landmark_id) -> None:
        self.marks[landmark_id] = LandmarkMark(ModelSelector(self.params.selection))

    def wants(self, mark: LandmarkMark) -> bool:
        """Count a sighting; True when it is one the selector takes (every ``classify_every``-th, while fed)."""
        mark.n_seen += 1
        return (mark.n_seen - 1) % self.params.classify_every == 0 and self.fed(mark)

    @staticmethod
    def under_review(mark: LandmarkMark) -> bool:
        """An articulated model's review window is open: not stopped, fewer observations than ``review_until``."""
        return not mark.refine_stopped and mark.selector.n_observations < mark.review_until

    @classmethod
    def fed(cls, mark: LandmarkMark) -> bool:
        """Whether the selector takes observations: undecided or static, or articulated and still under review."""
        return mark.status in ("undecided", "static") or (mark.status in ARTICULATED and cls.under_review(mark))

    # ------------------------------------------------------------ structures
    def _articulated_block(self, model_name: str, structure) -> ArticulatedBlock:
        p = self.params
        return ArticulatedBlock(get_model(model_name), structure, p.order(model_name),
                                p.sigma_eta(model_name), p.sigma_rate0(model_name), p.sigma_slip_m)

    def _common_axis(self):
        """Hinge axis of every landmark held revolute (:mod:`stslam.articulation.hinge_axis`), refitted when
        that set changes."""
        held = tuple(sorted(i for i, m in self.marks.items() if m.model == "revolute"))
        if held != self._axis_cache[0]:
            axes, points = {}, {}
            for i in held:
                structure = self._final_revolute(i)
                if structure is not None:
                    axes[i] = (structure.axis_point, structure.axis_direction)
                    points[i] = self.marks[i].selector.points
            try:
                axis = estimate_hinge_axis(axes, points, self.params.common_axis)
            except DegenerateFitError:
                axis = None
            self._axis_cache = (held, axis)
        return self._axis_cache[1]

    def _final_revolute(self, landmark_id):
        """The selector's final revolute structure, refitted only when it has taken new observations
        (the fit depends on nothing else)."""
        selector = self.marks[landmark_id].selector
        kept = self._final_fits.get(landmark_id)
        if kept is None or kept[0] is not selector or kept[1] != selector.n_observations:
            kept = self._final_fits[landmark_id] = (selector, selector.n_observations,
                                                    selector.final_structure("revolute"))
        return kept[2]

    def _structure(self, mark: LandmarkMark, name: str) -> tuple:
        """(structure for the block, the selector's structure it comes from); (None, …) when there is none yet.

        Revolute with ``common_axis``: the circle about the common axis through
        the landmark's selector points (:func:`stslam.articulation.hinge_axis.circle_on_axis`).
        """
        fitted = mark.selector.structure(name)
        if name != "revolute" or self.params.common_axis is None or fitted is None:
            return fitted, fitted
        axis = self._common_axis()
        if axis is None:
            return None, fitted
        try:
            return circle_on_axis(axis.point_world, axis.direction_world, mark.selector.points), fitted
        except DegenerateFitError:
            return None, fitted

    def _structure_scale(self, mark: LandmarkMark, model_name: str, corrected: bool = False) -> float:
        """R multiplier max(1, ρ²/σ²)(1 + κ p/n) for the block's structure, the selector's fit on n points.

        ρ is the structure's RMS residual (m): a structure that misses its own
        window by more than the sensor noise (a line through an arc) cannot predict better.
        κ is 0 for a ``corrected`` structure (its error is in the state).
        """
        model_filter = mark.selector.filter(model_name)
        sigma = self.params.selection.measurement_sigma_m
        misfit = max(1.0, (mark.structure.residual_m / sigma) ** 2)
        kappa = 0.0 if corrected else self.params.structure_inflation
        return misfit * (1.0 + kappa * STRUCTURE_DOF[model_name] / max(model_filter.n_fit, 1))

    def _set_scales(self, mark: LandmarkMark, model_name: str, corrected: bool) -> None:
        mark.fixed_scale = self._structure_scale(mark, model_name)
        # Under review the model and fit may still change (a door's first arc called a line): κ stays.
        settled = corrected and not self.under_review(mark)
        mark.r_scale = self._structure_scale(mark, model_name, True) if settled else mark.fixed_scale

    def _corrects(self, state) -> bool:
        """Whether articulated blocks carry their structure correction δ (``structure_state``, EKF states)."""
        return self.params.structure_state != "fixed" and isinstance(state, SlamState)

    def _add_correction(self, state: SlamState, landmark_id, mark: LandmarkMark, name: str) -> bool:
        """Append δ to the landmark's new articulated block (``structure_state``, SPEC 6.3(b)); False if not.

        δ = 0 (the fit) with covariance Σ_δ from the selector's fit points at σ = max(σ_z, ρ)
        (:func:`~stslam.articulation.correction.fit_correction_covariance`); with ``"pose"`` also
        A e_pose: the points were mapped through the pose estimate, whose error the fit kept.
        """
        if not self._corrects(state) or mark.selector.filter(name).fit_points is None:
            return False
        points = mark.selector.filter(name).fit_points
        sigma = max(self.params.selection.measurement_sigma_m, mark.structure.residual_m)
        try:
            cov, A = fit_correction_covariance(name, mark.structure, points, sigma, state.pose[:2])
        except (DegenerateFitError, ValueError):
            return False
        block = state.block(landmark_id)
        corrected = CorrectedArticulatedBlock(block.model, block.structure, block.order, block.sigma_eta,
                                              block.sigma_rate0, consider=self.params.structure_state == "consider")
        k, size = block.size, corrected.size
        x_b = np.concatenate([state.block_mean(landmark_id), np.zeros(size - k)])
        state.replace_block(landmark_id, corrected, x_b, np.eye(size, k), np.zeros((size, size)))
        A = A if self.params.structure_prior == "pose" else np.zeros_like(A)
        state.couple_to_pose(landmark_id, np.arange(k, size), A, cov)
        return True

    # ------------------------------------------------------------ block changes
    def convert(self, state: SlamState, landmark_id, z_robot, R, selector_rates: bool = True) -> bool:
        """Give the landmark its pending model's block, initialised from observation z (SPEC 6.3).

        q comes from z (inverse kinematics of m = R(θ)z + t, with the
        cross-covariance to the robot); the rates from the selector's filter on
        the same structure (``selector_rates``; sign-corrected when the block's
        circle turns the other way) or zero, each with ``sigma_rate0``² added.
        Returns False (the landmark stays as it is, still pending) when there is
        no structure yet.
        """
        mark = self.marks[landmark_id]
        name = mark.pending
        structure, fitted = self._structure(mark, name)
        if structure is None and mark.status == name:  # a restart without a new structure: keep the old one
            structure, fitted = mark.structure, mark.fitted
        if structure is None:
            return False
        mark.pending = None
        block = self._articulated_block(name, structure)
        state.remove_landmark(landmark_id)
        state.add_landmark(landmark_id, block, z_robot, R)  # q = IK(m), rates 0 with σ_rate0² prior
        if selector_rates and block.size > block.dof:
            # x_b ← [q, rates], J = diag(1, 0, …) keeps q and its correlations, extra = rate covariance;
            # the selector's rates fill the block's (the orders may differ: the rest stay 0 with σ_rate0²).
            model_filter = mark.selector.filter(name)
            x_b = state.block_mean(landmark_id)
            dof, size, n = block.dof, block.motion_size, min(block.motion_size, model_filter.x.size)
            x_b[dof:n] = model_filter.x[dof:n]
            if structure is not fitted:  # φ of a circle with the opposite normal runs backwards
                x_b[dof:size] *= float(np.sign(structure.normal @ fitted.normal) or 1.0)
            J = np.zeros((x_b.size, x_b.size))
            J[:dof, :dof] = np.eye(dof)
            extra = self.params.sigma_rate0(name) ** 2 * np.eye(x_b.size)
            extra[:dof, :dof] = 0.0
            extra[size:, size:] = 0.0  # the slip starts at 0 (ArticulatedBlock.initial)
            extra[dof:n, dof:n] += model_filter.P[dof:n, dof:n]
            state.replace_block(landmark_id, block, x_b, J, extra)
        mark.status, mark.structure, mark.fitted = name, structure, fitted
        self._set_scales(mark, name, self._add_correction(state, landmark_id, mark, name))
        return True

    def _rebase(self, state: SlamState, landmark_id, name: str, structure=None) -> None:
        """Carry the motion state onto the latest structure of model ``name`` (SPEC 6.3(b)), or onto
        ``structure`` when given (a revision's fit to the landmark's window)."""
        mark = self.marks[landmark_id]
        structure, fitted = (self._structure(mark, name) if structure is None
                             else (structure, mark.selector.structure(name)))
        if structure is None:
            return
        x_old = state.block_mean(landmark_id)
        old = state.block(landmark_id)
        n = old.motion_size
        if isinstance(old, CorrectedArticulatedBlock):  # δ is dropped: the new fit brings its own
            x_new, J = rebase_motion_state(mark.structure, structure, x_old[:n])
            J, extra = np.hstack([J, np.zeros((n, x_old.size - n))]), np.zeros((n, n))
        else:  # the slip, if any, stays as it is
            x_new, J, extra = x_old.copy(), np.eye(x_old.size), np.zeros((x_old.size, x_old.size))
            x_new[:n], J[:n, :n] = rebase_motion_state(mark.structure, structure, x_old[:n])
        state.replace_block(landmark_id, self._articulated_block(name, structure), x_new, J, extra)
        mark.status, mark.structure, mark.fitted = name, structure, fitted
        self._set_scales(mark, name, self._add_correction(state, landmark_id, mark, name))
        mark.rebases += 1

    def _to_static(self, state: SlamState, landmark_id) -> None:
        """Articulated → static point: m = f(C, q), J = ∂m/∂X = [∂f/∂q, 0, …] (SPEC 2)."""
        mark = self.marks[landmark_id]
        m, dm_dx = state.block(landmark_id).position(state.block_mean(landmark_id))
        state.replace_block(landmark_id, self.static_block, m, dm_dx, np.zeros((3, 3)))
        mark.structure, mark.fitted, mark.r_scale, mark.fixed_scale = None, None, 1.0, 1.0

    def restart(self, state: SlamState, landmark_id, z_robot, R) -> None:
        """A decided landmark failed the gate ``restart_after`` times while others passed: it moved, or was lost.

        Static: the point is re-initialised from z and goes back under selection
        (the same selector, which keeps its history). Articulated: its motion state
        is re-initialised from z on the same model (rates from the selector while
        it is fed, else zero) and its review is reopened.
        """
        mark = self.marks[landmark_id]
        if mark.status == "static":
            state.remove_landmark(landmark_id)
            state.add_landmark(landmark_id, self.static_block, z_robot, R)
            mark.status, mark.anchor, mark.window = "undecided", None, []
        else:
            reviewing = self.under_review(mark)
            mark.pending = mark.status
            mark.review_until = mark.selector.n_observations + self.params.refine_until  # (before the block
            mark.refine_stopped = False  # is made: a corrected structure waits for the review's end)
            self.convert(state, landmark_id, z_robot, R, selector_rates=reviewing)
        mark.rejections = 0
        mark.restarts += 1

    # ------------------------------------------------------------ selection
    def select(self, state: SlamState, landmark_id, m_world, k: int, times_s, cov=None) -> None:
        """Feed one world-frame point to the landmark's selector; act on a held decision or a refit.

        ``times_s`` (n,) are the frame times (s); ``cov`` (3, 3), if given, the point's
        covariance (m²). A decision is the selector's current model (μ_j > τ, SPEC 4,
        and its decision gates) at ``hold_steps`` consecutive observations.
        Undecided and static landmarks are fed (a static one is converted when
        its selector decides an articulated model);
        an articulated one is fed for ``refine_until`` more observations after
        each decision or restart, during which its structure is refined and it
        may switch to the other model; back to static only if it has not been
        seen moving (moved less than ``moved_m`` from where it started).
        """
        params, mark = self.params, self.marks[landmark_id]
        if not self.fed(mark):
            return
        reviewing = mark.status in ARTICULATED
        if mark.status != "static":  # only a static point's selector may rest (its μ and structures wait,
            mark.selector.wake()  # docs/selection.md §7): a restarted or articulated one uses them
        gap = None if mark.last_frame is None else float(times_s[k] - times_s[mark.last_frame])
        try:
            mu = mark.selector.observe(m_world, gap, cov)
        except InnovationCovarianceError:
            # A model's filter broke down (e.g. a near-infinite circle fitted to a line, predicted
            # across a long gap). Under review: keep the model in use. Undecided: start over here.
            mark.selector_failures += 1
            if reviewing:
                mark.refine_stopped = True
                return
            mark.n_fed += mark.selector.n_observations
            mark.selector = ModelSelector(params.selection)
            mu = mark.selector.observe(m_world, None, cov)
        mark.last_frame = k
        mark.mu_frames.append(k)
        names = mark.selector.names
        mark.mu_rows.append(np.full(len(names), np.nan) if mu is None else mu)
        best = mark.selector.held_model  # its decision, held for ``hold_steps`` consecutive observations
        seen_moving = mark.selector.moved_m > params.moved_m
        action = selector_action(mark.model, mark.status, best, seen_moving, params.convert, self.revises,
                                 mark.selector.held_steps, params.static_hold)
        if action is not None:
            mark.decisions.append((k, mark.n_fed + mark.selector.n_observations - 1, best))
            mark.held = None
            if action == "static":
                if mark.status in ARTICULATED:
                    self._to_static(state, landmark_id)
                mark.status, mark.pending = "static", None
            elif action == "hold":
                mark.held, mark.pending = best, None  # recorded only; a pending conversion lapses
            elif action == "rebase":
                self._rebase(state, landmark_id, best)
            else:
                mark.pending = best
            if best in ARTICULATED:
                mark.review_until = mark.selector.n_observations + params.refine_until
        elif (mark.status in ARTICULATED and mark.selector.structure(mark.status) is not mark.fitted
              and not (isinstance(block := state.block(landmark_id), CorrectedArticulatedBlock)
                       and not block.consider)):
            self._rebase(state, landmark_id, mark.status)  # (an updated δ refines its structure instead)
        if self._corrects(state) and mark.status in ARTICULATED and mark.pending is None and not self.fed(mark):
            self._settle(state, landmark_id)  # its last observation under review

    def _settle(self, state: SlamState, landmark_id) -> None:
        """The review is over (``structure_state`` corrected): the block's structure is from now on
        corrected in the state by every observation, with κ = 0."""
        mark = self.marks[landmark_id]
        corrected = isinstance(state.block(landmark_id), CorrectedArticulatedBlock)
        self._set_scales(mark, mark.status, corrected or self._add_correction(state, landmark_id, mark, mark.status))
