"""A-SLAM on RGB-D feature tracks: static-gated landmarks that become articulated once classified (SPEC 6.3, 8.5).

Built only from shared parts: the SLAM core and blocks (:mod:`stslam.slam`),
the online selector (:class:`stslam.selection.ModelSelector`, SPEC 4) and the
driver of :mod:`stslam.rgbd_slam`. The rule per landmark (track):

1. **From first sight** it serves as a static point (random walk
   ``sigma_walk``) whose observations pass a χ² innovation gate
   (``gate_probability``, 3 dof) — SPEC 6.3(a): static landmarks help at
   once, and a point that starts to move is not trusted blindly.
2. **Selection.** Every ``classify_every``-th observation, mapped to the world
   with the filter's current pose (m = R(θ) z + [x, y, 0]ᵀ), is fed to the
   landmark's selector; the gap between fed observations is its δt (s). The
   landmark's model is the selector's held decision (μ_j > τ for
   ``hold_steps`` steps in a row); with the switching IMM selector a point
   first held static (a closed door) can later be held revolute.
3. **Conversion** once the held model is one of ``convert`` (articulated
   models, by default both): it replaces the static block by an articulated block
   (:class:`stslam.slam.blocks.ArticulatedBlock`, order ``order``) on the
   selector's structure, refitted on its growing window (SPEC 6.3(b): never
   the first N_min points only). The block starts from the frame's own
   observation like a new landmark (q by inverse kinematics, correlated with
   the robot), its rates from the selector's filter (their covariance plus
   ``sigma_rate0``²): the static point it replaces is stale, since the gate
   rejected the observations of the moving point. With ``common_axis`` set
   (options of :func:`stslam.hinge_axis.estimate_hinge_axis`), a revolute
   landmark's structure is instead its circle about the hinge axis fitted
   jointly on every landmark held revolute so far
   (:func:`stslam.hinge_axis.circle_on_axis`); it waits, as a gated static
   point, until that many agree. Any other decision keeps the gated static block. Articulated landmarks stay gated
   too. The fridge configuration converts only ``revolute``: in a room with
   one hinged door, the tracks held prismatic were corners sliding along an
   occlusion edge, and converting them raised the mean ATE on the development
   seeds (100–102).

What the development seeds showed: while the door swings, the converted door
points make A-SLAM *better* than the gated EKF (0.005 vs 0.015 m at the end
of the opening); when the door speeds up or stops, the two dozen door points,
each with its own angle, disagree with their constant-velocity model together
and pull the robot's heading. A σ_η of the door's real acceleration (≈ 1.2
rad/s² peak, hence 3 rad/s²), structures from the common axis and waiting for
8 agreeing tracks before converting (an axis from 3 short arcs is off by
degrees) reduce that pull but do not remove it.

Why this differs from the paper's real-data A-SLAM (SPEC 8.5, Table III: worse
than EKF SLAM): there every landmark waited for its model and moving points
were forced into whichever model won. Here a wrong or undecided model costs
nothing but a gated static point, and the sliding corners the tracker
produces at occlusion edges fail the gate instead of dragging the robot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from stslam.errors import DegenerateFitError
from stslam.hinge_axis import circle_on_axis, estimate_hinge_axis
from stslam.rgbd_slam import run_rgbd_filter
from stslam.rgbd_tracks import SequenceTracks
from stslam.selection import ModelSelector
from stslam.selection_settings import SelectionSettings
from stslam.sensor import point_from_observation
from stslam.slam.blocks import ArticulatedBlock, StaticPointBlock
from stslam.slam.filters import FilterSpec, FilterTrack

ARTICULATED = ("prismatic", "revolute")


@dataclass(frozen=True)
class ASlamSettings:
    """A-SLAM parameters (see the module docstring); ``convert`` lists the models that get an articulated block.

    ``sigma_eta`` and ``sigma_rate0`` map a model name to the std of its motion
    state's noise (q unit per s^(order+1)) and of its initial rates (q unit per s);
    q is in m for prismatic and rad for revolute (SPEC 2).
    """

    selection: SelectionSettings
    classify_every: int = 3
    sigma_walk: float = 0.0
    gate_probability: float = 0.99
    order: int = 1
    sigma_eta: dict = None
    sigma_rate0: dict = None
    convert: tuple = ARTICULATED
    common_axis: dict | None = None


@dataclass
class LandmarkRecord:
    """What A-SLAM decided for one landmark.

    ``model`` is the held model (None while undecided) and ``frame`` the frame
    it was decided at; ``fed_frames`` the frames whose observation the selector got.
    """

    selector: ModelSelector
    model: str | None = None
    frame: int | None = None
    last_fed_t: float | None = None
    n_seen: int = 0
    fed_frames: list = None
    pending: bool = False


@dataclass(frozen=True)
class ASlamResult:
    """A-SLAM's pose track and its per-landmark records (id → :class:`LandmarkRecord`)."""

    track: FilterTrack
    records: dict


class _Rule:
    """The after-frame hook of :func:`run_rgbd_aslam` (feeds selectors, converts blocks)."""

    def __init__(self, settings: ASlamSettings, times_s):
        self.s = settings
        self.times = np.asarray(times_s, dtype=float)
        self.records: dict = {}
        self._axis_cache = (None, None)  # (ids the axis was fitted on, HingeAxis or None)

    def __call__(self, k: int, state, ids, z, R) -> None:
        for j, i in enumerate(ids.tolist()):
            record = self.records.get(i)
            if record is None:
                record = self.records[i] = LandmarkRecord(ModelSelector(self.s.selection), fed_frames=[])
            record.n_seen += 1
            if record.pending and i in state:
                self._convert(state, i, record, z[j], R[j])
            if record.model in self.s.convert or (record.n_seen - 1) % self.s.classify_every:
                continue
            m, _, _ = point_from_observation(state.pose, z[j])
            dt = None if record.last_fed_t is None else self.times[k] - record.last_fed_t
            record.last_fed_t = self.times[k]
            record.selector.observe(m, dt if dt and dt > 0 else None)
            record.fed_frames.append(k)
            held = self._held(record.selector)
            if held is None or held == record.model:
                continue
            record.model, record.frame = held, k
            record.pending = held in self.s.convert  # a pending conversion lapses if the decision changes
            if record.pending and i in state:
                self._convert(state, i, record, z[j], R[j])

    def _held(self, selector: ModelSelector) -> str | None:
        """The model held over the last ``hold_steps`` steps (μ > τ after the motion gate), else None."""
        recent = selector.current_history[-selector.settings.hold_steps:]
        if len(recent) < selector.settings.hold_steps or recent[0] is None:
            return None
        return recent[0] if all(c == recent[0] for c in recent) else None

    def _common_axis(self):
        """Hinge axis of every landmark held revolute (:mod:`stslam.hinge_axis`), refitted when that set grows."""
        held = tuple(sorted(i for i, r in self.records.items() if r.model == "revolute"))
        if held != self._axis_cache[0]:
            axes, points = {}, {}
            for i in held:
                structure = self.records[i].selector.final_structure("revolute")
                if structure is not None:
                    axes[i] = (structure.axis_point, structure.axis_direction)
                    points[i] = self.records[i].selector.points
            try:
                axis = estimate_hinge_axis(axes, points, **self.s.common_axis)
            except DegenerateFitError:
                axis = None
            self._axis_cache = (held, axis)
        return self._axis_cache[1]

    def _structure(self, record: LandmarkRecord):
        """Structure for the block and the sign relating its q to the selector filter's q (None: not yet)."""
        selector = record.selector
        model_filter = selector.filters[selector.names.index(record.model)]
        if model_filter.structure is None:
            return None, 1.0
        if record.model != "revolute" or self.s.common_axis is None:
            return model_filter.structure, 1.0
        axis = self._common_axis()
        if axis is None:
            return None, 1.0
        structure = circle_on_axis(axis.point_world, axis.direction_world, selector.points)
        return structure, float(np.sign(structure.normal @ model_filter.structure.normal) or 1.0)

    def _convert(self, state, landmark_id, record: LandmarkRecord, z_robot, R) -> None:
        """Re-initialise the landmark from observation z (3,) with noise R (3, 3) on its held model's block.

        Without a structure yet (no common axis), the landmark stays a static point and ``pending``.
        """
        structure, sign = self._structure(record)
        if structure is None:
            return
        record.pending = False
        selector = record.selector
        model_filter = selector.filters[selector.names.index(record.model)]
        block = ArticulatedBlock(model_filter.model, structure, self.s.order,
                                 self.s.sigma_eta[record.model], self.s.sigma_rate0[record.model])
        state.remove_landmark(landmark_id)
        state.add_landmark(landmark_id, block, z_robot, R)  # q = IK(m), m from z and the pose
        # Rates [q⁽¹⁾, …] from the selector's filter (sign-corrected for a flipped normal):
        # x_b ← [q, rates] with J = diag(I, 0) (q and its correlations kept), the rates' covariance added.
        idx = state.indices(landmark_id)
        dof = block.dof
        x_b = state.x[idx].copy()
        n_rates = min(idx.size, model_filter.x.size) - dof
        x_b[dof:dof + n_rates] = sign * model_filter.x[dof:dof + n_rates]
        J = np.zeros((idx.size, idx.size))
        J[:dof, :dof] = np.eye(dof)
        extra = self.s.sigma_rate0[record.model] ** 2 * np.eye(idx.size)
        extra[:dof, :dof] = 0.0
        extra[dof:dof + n_rates, dof:dof + n_rates] += model_filter.P[dof:dof + n_rates, dof:dof + n_rates]
        state.replace_block(landmark_id, block, x_b, J, extra)


def run_rgbd_aslam(settings: ASlamSettings, tracks: SequenceTracks, inputs: list, alpha) -> ASlamResult:
    """Run A-SLAM over a recording's landmark inputs (:func:`stslam.rgbd_slam.frame_inputs`)."""
    rule = _Rule(settings, tracks.times_s)
    static = StaticPointBlock(settings.sigma_walk)
    spec = FilterSpec("a_slam", lambda i: static, float(chi2.ppf(settings.gate_probability, 3)))
    track = run_rgbd_filter(spec, tracks, inputs, alpha, after_frame=rule)
    return ASlamResult(track, rule.records)
