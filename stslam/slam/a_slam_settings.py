"""Settings of A-SLAM (SPEC 6.3); the hinge-axis options it may share among revolute landmarks are
:class:`stslam.articulation.hinge_axis.HingeAxisOptions`.

Read (:mod:`stslam.config.slam`) from the config block ``filters.a_slam``
(``conf/exp/dynamic_slam.yaml``, its two process noises per world in
``conf/tuning/<world>.yaml``; ``conf/exp/fridge.yaml``) and the ``selection``
block (``conf/selection/slam.yaml``, ``rgbd_tracks.yaml``; SPEC 4).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

from scipy.stats import chi2

from stslam.articulation.hinge_axis import AxisTolerance, HingeAxisOptions
from stslam.selection.settings import SelectionSettings

ARTICULATED = ("prismatic", "revolute")
SELECTION_COVARIANCES = ("relative", "pose", "sensor")
STRUCTURE_STATES = ("fixed", "corrected", "consider")
STRUCTURE_PRIORS = ("pose", "sensor")
EVIDENCE_POSES = ("static", "posterior")
ARTICULATED_UPDATES = ("each", "joint")
ANGULAR = ("revolute",)


@dataclass(frozen=True)
class BodySettings:
    """Grouping of landmarks into articulated bodies (SPEC 13, :mod:`stslam.slam.bodies`).

    Attributes
    ----------
    significance : float
        A pair is rigid unless the χ² test of constant distance rejects it at this level.
    window : int
        Common frames (the latest) the test uses.
    min_common : int
        Fewest common frames for a test.
    min_motion_m : float
        Both tracks must have moved this far over those frames (m; ``RigidityTest.spread_m``).
    joint_tolerance : AxisTolerance
        How closely a decided candidate's joint must agree with the founder's
        (axis angle, axis-line distance).
    every : int
        Frames between grouping passes (and revision passes).
    evidence_window : int
        Latest sightings of each landmark kept for grouping and for the window evidence of its
        model (frames).
    revision_margin : float
        Hysteresis of a body's revision (:mod:`stslam.slam.bodies.decisions`): its prismatic/revolute model
        switches when the pooled window log-odds favour the other by more than this (nats).
    revise : bool
        Whether bodies' models are revised from the pooled window evidence at all (ablation).
    evidence_pose : {"static", "posterior"}
        The pose each kept sighting is mapped to the world with (grouping tests and window evidence) under
        the EKF: ``"static"``, the frame's pose after its static points' joint update and before the
        articulated landmarks' own updates, so that a moving body's sightings do not confirm its current
        model through a pose they corrected themselves; ``"posterior"``, the pose after every update of
        the frame. A factor graph keeps its posterior pose either way.
    """

    significance: float = 0.01
    window: int = 30
    min_common: int = 10
    min_motion_m: float = 0.1
    joint_tolerance: AxisTolerance = AxisTolerance()
    every: int = 5
    evidence_window: int = 120
    revision_margin: float = 3.0
    revise: bool = True
    evidence_pose: str = "static"


@dataclass(frozen=True)
class ArticulatedNoise:
    """Noise of an articulated block (SPEC 3), linear for static and prismatic q, angular for revolute φ:
    process noise σ_η (``sigma_eta_m`` m/s^(k+1), ``sigma_eta_rad`` rad/s^(k+1)) and the std of the rates
    when the block starts (``sigma_rate0_m`` m/s, ``sigma_rate0_rad`` rad/s). A-SLAM's blocks and the
    oracle's are alike (:class:`ASlamParams`, :class:`stslam.slam.filters.OracleParams`)."""

    sigma_eta_m: float
    sigma_eta_rad: float
    sigma_rate0_m: float
    sigma_rate0_rad: float

    def sigma_eta(self, model_name: str) -> float:
        """σ_η of a block of model ``model_name``."""
        return self.sigma_eta_rad if model_name in ANGULAR else self.sigma_eta_m

    def sigma_rate0(self, model_name: str) -> float:
        """Prior std of the rates of a block of model ``model_name``."""
        return self.sigma_rate0_rad if model_name in ANGULAR else self.sigma_rate0_m


@dataclass(frozen=True)
class ASlamParams(ArticulatedNoise):
    """A-SLAM settings (module docstring); units per frame when δt is one frame.

    Attributes
    ----------
    selection : SelectionSettings
        Model selection (SPEC 4); its ``order`` is also the order of the
        articulated motion states (SPEC 3) unless ``block_order`` is given.
    sigma_walk : float
        Random walk of static points (m/√s).
    gate_probability : float
        Probability of the χ² (3 dof) innovation gate on every observation.
    sigma_eta_m, sigma_eta_rad : float
        Process noise σ_η of prismatic q (m/s^(k+1)) and revolute φ (rad/s^(k+1)).
    sigma_rate0_m, sigma_rate0_rad : float
        Std added to the selector's rate estimates at conversion (m/s, rad/s).
    structure_inflation : float
        κ in R(1 + κ p/n) for articulated observations.
    refine_until : int
        Observations after which an articulated structure is no longer refitted.
    restart_after : int
        Consecutive gate rejections that restart a decided landmark.
    max_pose_sigma_m : float or None
        An observation is given to selection only when the robot's pose
        uncertainty moves its world point by at most this std (m, largest
        axis of J_pose P_pose J_poseᵀ); None or inf: no such guard (the
        default: ``selection_covariance`` weighs that uncertainty instead).
    selection_covariance : {"relative", "pose", "sensor"}
        The covariance each point given to selection carries, for the
        selector's filters and its motion and curvature tests (SPEC 13,
        :func:`stslam.slam.a_slam.selection_covariances`): the sensor noise in
        the world plus the pose's share, ``"pose"`` J_pose P_pose J_poseᵀ, or
        ``"relative"`` the same less the part the pose has in common with the
        landmark's estimate (the innovation covariance in world axes);
        ``"sensor"``: σ_z² I only.
    moved_m : float
        A landmark whose selector saw it this far (m) from where it started
        has been seen moving and is never made static again.
    static_hold : int
        An articulated landmark not seen moving is made static again only once its selector has
        called it static for this many consecutive observations (1: as soon as the verdict is held,
        Algorithm 1). A hysteresis on undoing a conversion: a door point seen again after a long gap
        has its moving models' predictions spread wide, so one sighting can tip μ to static.
    convert : tuple of str
        Articulated models whose decision gives the landmark that model's
        block; a decision for another one is only recorded (the landmark stays
        an undecided gated static point and its selector is fed on).
    classify_every : int
        Only every n-th observation of a landmark goes to its selector.
    common_axis : HingeAxisOptions or None
        Options of :func:`stslam.articulation.hinge_axis.estimate_hinge_axis`: a revolute
        landmark's structure is then its circle about the axis fitted jointly on
        every landmark held revolute (and waits, as a gated static point, until
        ``min_tracks`` of them agree); None: each landmark's own fitted circle.
    bodies : BodySettings or None
        Landmarks moving rigidly together share one joint and motion state
        (SPEC 13, :mod:`stslam.slam.bodies`); None: every landmark on its own.
    block_order : int or None
        Temporal order k of the articulated blocks' motion states (SPEC 3), so
        that they can be the oracle's; None: the selection's order.
    structure_state : {"fixed", "corrected", "consider"}
        ``"corrected"``: SPEC 6.3(b)'s "keep them in the state", on the EKF
        (an iSAM2 state has its own, ``isam2.structure``): an articulated block
        carries its structure's correction δ
        (:class:`~stslam.slam.blocks.CorrectedArticulatedBlock`), zero at
        conversion with the fit's first-order covariance (``structure_prior``);
        every observation then refines δ, refits of its model are no longer
        carried in (they would count its observations twice), and κ applies
        only while the landmark is under review (``refine_until``: its model
        may still change). ``"consider"``: δ the same, but a consider parameter
        (Schmidt–Kalman): never updated, its covariance and cross-covariances
        enter every innovation and gain; refits are carried in (each with a new δ
        of its own fit's covariance), κ as for ``"corrected"``.
        ``"fixed"``: the structure is held as fitted, κ covering its error.
    structure_prior : {"pose", "sensor"}
        δ's prior: ``"sensor"``, Σ_δ of the sensor noise on the fit's points
        (:func:`stslam.articulation.correction.fit_correction_covariance`);
        ``"pose"``, plus the error of the pose the points were mapped through,
        taken as the robot's current one (A P_rr Aᵀ added and the
        cross-covariance A P_r·, as a new point is placed).
    onset_allowance, onset_threshold : float or None
        CUSUM of a static point's NIS (3 dof, mean 3): g ← max(0, g + NIS − allowance); above
        ``onset_threshold`` the point has begun to move (a drawer sliding slowly enough for each
        step to pass the gate) and is held out of the update until it rests again; None: off.
    onset_quiet : int
        Frames in a row whose NIS stays under ``onset_allowance`` after which a held-out point is
        at rest again (it is re-placed at its observation by the restarts meanwhile).
    onset_frame_quantile : float
        The allowance is at least twice this quantile of the frame's static NIS: when even the
        best-fitting points of a frame have a high NIS, the robot is off (or the filter's covariance
        too small), and that is no point's motion. 0.5 (the median) takes a minority for the movers;
        a lower one lets a majority move together (a fridge door filling the view) while the
        rest, still fitting, hold the robot (``stslam.slam.onsets.onsets``).
    onset_drift_probability : float or None
        A second onset test, for a point the filter follows as it moves (a young point's
        estimate moves with it, so its NIS stays small): its estimate m has moved from an
        anchor (m_a, P_a) more than refinement explains, (m − m_a)ᵀ(P_a − P)⁻¹(m − m_a) above
        the χ² quantile (3 dof) of this probability; None: off (``stslam.slam.onsets.drifted``). EKF
        states only: a smoother revises its past estimates, so their changes are no such test.
    onset_windows : tuple of int
        A third onset test, for a point that rests displaced from its estimate (it moved while followed, or
        its estimate averaged a stretch of motion): over each of these numbers of its latest static
        sightings, the sum of its innovations (world axes) against the sum of their covariances, a χ²
        test (3 dof) of a common mean (``stslam.slam.onsets.shifted``); () : off. EKF states only.
    onset_window_probability : float
        Its probability per frame, shared among the window lengths (Bonferroni).
    onset_replay : int
        When a point is flagged, roll the EKF back to the frame at which its CUSUM began to rise, at
        most this many frames, and redo the frames since without its observations, the
        conversions, restarts and bodies of those frames redone in their place (:mod:`stslam.slam.replay`);
        0: off. EKF states only.
    onset_withdraw : int
        The smoother's counterpart: when a point is flagged, its observation factors since its CUSUM
        rose, at most this many frames back, are taken out of the graph
        (:func:`stslam.graph.reread.withdraw`); 0: off. Factor-graph states only.
    articulated_update : {"each", "joint"}
        How a frame's articulated observations enter an EKF, after its static points: ``"each"``, one
        by one, each gated against the state its predecessor left; ``"joint"``, each gated on its own
        against the state the static points left, the accepted ones in one update (as a factor graph
        takes them): one n × 6k × n product instead of k of n × 6 × n and k symmetrisations.
    sigma_slip_m : float
        Std of the random walk of each articulated landmark's slip off its
        structure (m/√s; :class:`~stslam.slam.blocks.ArticulatedBlock`), for
        tracked features that creep over a moving part; 0: no slip.
    """

    selection: SelectionSettings
    sigma_walk: float
    gate_probability: float
    structure_inflation: float = 100.0
    refine_until: int = 60
    restart_after: int = 3
    max_pose_sigma_m: float | None = None
    selection_covariance: str = "relative"
    moved_m: float = 0.2
    static_hold: int = 5
    convert: tuple = ARTICULATED
    classify_every: int = 1
    common_axis: HingeAxisOptions | None = None
    bodies: BodySettings | None = None
    block_order: int | None = None
    structure_state: str = "fixed"
    structure_prior: str = "pose"
    sigma_slip_m: float = 0.0
    onset_allowance: float | None = 6.0
    onset_threshold: float = 10.0
    onset_quiet: int = 5
    onset_frame_quantile: float = 0.5
    onset_drift_probability: float | None = 0.999
    onset_windows: tuple = ()
    onset_window_probability: float = 0.99
    onset_replay: int = 30
    onset_withdraw: int = 0
    articulated_update: str = "each"

    @cached_property  # (frozen: computed once per instance)
    def max_nis(self) -> float:
        return float(chi2.ppf(self.gate_probability, 3))

    @cached_property  # (frozen: computed once per instance)
    def window_bound(self) -> float:
        """χ²₃ quantile of the windowed shift test, Bonferroni over ``onset_windows`` (``stslam.slam.onsets.shifted``)."""
        return float(chi2.ppf(1.0 - (1.0 - self.onset_window_probability) / max(1, len(self.onset_windows)), 3))

    @cached_property  # (frozen: computed once per instance)
    def drift_bound(self) -> float | None:
        """χ²₃ quantile of ``onset_drift_probability`` (``stslam.slam.onsets.drifted``); None when off."""
        p = self.onset_drift_probability
        return None if p is None else float(chi2.ppf(p, 3))

    def order(self, model_name: str) -> int:
        """Temporal order of the articulated block of ``model_name`` (SPEC 3)."""
        return self.selection.filters[model_name].order if self.block_order is None else self.block_order

