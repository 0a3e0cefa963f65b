"""How the iSAM2 back end is run: :class:`Isam2Settings` (SPEC 14), read by :mod:`stslam.graph.solver` and
:mod:`stslam.graph.state`, filled from the config by :mod:`stslam.config.backend`."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Isam2Settings:
    """How the iSAM2 back end is run.

    Attributes
    ----------
    relinearize_threshold : float
        iSAM2's relinearisation threshold on a variable's update (units of the variable): on a pose's
        heading (rad) and on every landmark state but a static point's.
    relinearize_threshold_m : float
        The threshold on a pose's position, a static point's and a constant-velocity point's position and
        velocity (m, m/s). Every factor is linear in these for a fixed heading (h = R(θ)ᵀ(m − t), odometry
        x' = x + R(θ)·d, SPEC 5.1, 5.2; m_t = m_{t−1} + δt ṁ, SPEC 6.2): a position's update changes only the
        heading's Jacobians, so the linearised factor misses by at most δθ·(|δm| + |δt|) (δθ below
        ``relinearize_threshold``), and the positions can wait for larger updates than the angles (:func:`key_letter`).
    relinearize_threshold_q : float or None
        The threshold on an articulated landmark's motion variable q (m or rad; the first entry of its motion
        state, the whole state at order 0) where its model has one degree of freedom; None: ``relinearize_threshold``.
        A point reads q through f(C, q), smooth on the scale of the joint: a line is linear in q, a circle of
        radius r bends away from its tangent by r·δq²/2 (SPEC 2.2, 2.3).
    relinearize_skip : int
        Relinearisation is checked every this many updates (iSAM2's own schedule), unless
        ``relinearize_frames`` is set.
    relinearize_frames : int or None
        The full smoother checks relinearisation at the first update of every this many frames
        instead (forced at that update, never otherwise): a schedule in frames does not change with
        how many updates a frame needs (:class:`~stslam.graph.state.GraphState` flushes its buffer
        whenever an estimate is asked for). The fixed-lag smoother keeps ``relinearize_skip``.
    floor_sigma : float
        Standard deviation added to singular factor covariances (units of the variable).
    final_iterations : int
        At most this many relinearisations after the last frame (iSAM2's, of the variables whose update
        exceeds its threshold), towards the batch optimum; they stop at one that relinearises nothing.
    factorization : {"cholesky", "qr"}
        iSAM2's elimination: Cholesky (faster) or QR (stabler on badly conditioned graphs). Under Cholesky the
        full smoother falls back to QR for the rest of the run where Cholesky finds the system indeterminate
        (:class:`~stslam.graph.solver.FullSolver`); the fixed-lag smoother (``lag_s``) does not. The
        experiments' configs choose Cholesky; the default here stays QR, which graphs of near-exact factors
        (floors of 1e-7, as in the tests) need.
    reread : bool
        At a conversion from a static point to an articulated block, re-read the point's past
        observations as the block's (:mod:`stslam.graph.reread`; full smoother only).
    reread_restarts : bool
        With ``reread``, a conversion re-reads also the static chains that A-SLAM's restarts of the
        landmark ended before its current one (:mod:`stslam.graph.reread`).
    lag_s : float or None
        None: iSAM2 over the whole run; else a fixed-lag smoother that marginalises variables no
        factor has touched for this many seconds (:mod:`stslam.graph.solver`).
    reread_refits : bool
        At each refit of an articulated block, re-read all of the landmark's observations on the new
        structure and its current noise (:mod:`stslam.graph.reread`; full smoother only), so that the
        final graph reads every observation with the latest structure.
    reread_refit_frames : int
        A landmark's refit re-read waits until this many frames have passed since its last one (1: every
        refit at the landmark's next update). A refit that comes while one waits supersedes it (the
        re-read reads everything on the latest structure), and one still waiting after the last frame is
        done then, so the final graph is the same kind; each re-read re-eliminates the landmark's whole
        past in iSAM2 (:mod:`stslam.graph.reread`).
    windowed : tuple of str
        Filters (:data:`stslam.slam.filters.FILTER_NAMES`) run with ``lag_s``; the others run with
        ``lag_s = None`` (:func:`stslam.graph.run.run_filter_isam2`).
    structure : {"fixed", "variable"}
        An articulated block's structure: fixed at its fit (the EKF's way), or corrected by a graph
        variable that all its observations estimate (:mod:`stslam.graph.structure`); then A-SLAM's
        structure inflation κ, which stands in for the error of a fixed structure, is not applied.
    regate_probability : float or None
        After the last frame, each observation a gate kept out is tested again against the smoothed
        estimate with the χ² bound of this probability (3 dof) and becomes a factor if it passes
        (:mod:`stslam.graph.regate`; full smoother only); None: gated-out observations stay out.
    regate_robust : bool
        Those that fail the re-test too enter with a Huber kernel at the same bound (:mod:`stslam.graph.regate`).
    observe_every : int
        Observations enter the graph at every this many frames only, odometry at every frame
        (:func:`stslam.slam.loop.run_slam`), so that a tracked feature whose error persists over many
        frames (the fridge's stay correlated for about a second) is not read as that many independent
        observations by a smoother that holds them all at once.
    structure_sigma : float
        Std of the prior at zero of each structure correction δ (``structure == "variable"``; m for a shift
        or a radius, rad for a tilt, 1 for a line's shear, :mod:`stslam.articulation.correction`). The
        observations read on one fitted structure often span little of its motion (a door refitted while
        at rest: q within 0.02-0.1 rad), and leave most of δ to this prior: at 10 the kitchen's circles
        wandered metres and turns from their fits, where the articulated factors are then linearised.
    structure_sigma_final : float or None
        After the last frame (and the re-test), each δ's prior std becomes this, followed by the
        relinearisations of ``final_iterations`` (full smoother only): the prior sits at a fit made from
        observations the graph also holds, so it counts them a second time
        (:meth:`stslam.graph.observing.StructureKeys.loosen`). None: ``structure_sigma`` throughout.
    """

    relinearize_threshold: float = 0.01
    relinearize_threshold_m: float = 0.01
    relinearize_threshold_q: float | None = None
    relinearize_skip: int = 10
    relinearize_frames: int | None = None
    floor_sigma: float = 1e-4
    final_iterations: int = 3
    factorization: str = "qr"
    reread: bool = False
    reread_restarts: bool = False
    lag_s: float | None = None
    windowed: tuple = ()
    reread_refits: bool = True
    reread_refit_frames: int = 1
    structure: str = "variable"
    regate_probability: float | None = 0.99
    regate_robust: bool = True
    observe_every: int = 1
    structure_sigma: float = 10.0
    structure_sigma_final: float | None = None

    def __post_init__(self):
        if self.structure not in ("fixed", "variable"):
            raise ValueError(f"Isam2Settings: structure must be fixed or variable, got {self.structure!r}")
        if self.factorization not in ("cholesky", "qr"):
            raise ValueError(f"Isam2Settings: factorization must be cholesky or qr, got {self.factorization!r}")
        if not (self.relinearize_threshold > 0 and self.relinearize_threshold_m > 0 and self.floor_sigma > 0
                and self.structure_sigma > 0):
            raise ValueError("Isam2Settings: relinearize_threshold, relinearize_threshold_m, floor_sigma and "
                             "structure_sigma must be > 0")
        if self.structure_sigma_final is not None and not self.structure_sigma_final > 0:
            raise ValueError(f"Isam2Settings: structure_sigma_final must be None or > 0, "
                             f"got {self.structure_sigma_final!r}")
        if self.relinearize_threshold_q is not None and not self.relinearize_threshold_q > 0:
            raise ValueError(f"Isam2Settings: relinearize_threshold_q must be None or > 0, "
                             f"got {self.relinearize_threshold_q!r}")
        if self.relinearize_skip < 1 or self.final_iterations < 0:
            raise ValueError("Isam2Settings: relinearize_skip must be ≥ 1 and final_iterations ≥ 0")
        if self.relinearize_frames is not None and (isinstance(self.relinearize_frames, bool)
                                                    or not isinstance(self.relinearize_frames, int)
                                                    or self.relinearize_frames < 1):
            raise ValueError(f"Isam2Settings: relinearize_frames must be None or an integer ≥ 1, "
                             f"got {self.relinearize_frames!r}")
        if self.regate_probability is not None and not 0.0 < self.regate_probability < 1.0:
            raise ValueError(f"Isam2Settings: regate_probability must be None or in (0, 1), "
                             f"got {self.regate_probability!r}")
        if isinstance(self.reread_refit_frames, bool) or not isinstance(self.reread_refit_frames, int) \
                or self.reread_refit_frames < 1:
            raise ValueError(f"Isam2Settings: reread_refit_frames must be an integer ≥ 1, "
                             f"got {self.reread_refit_frames!r}")
        if isinstance(self.observe_every, bool) or not isinstance(self.observe_every, int) or self.observe_every < 1:
            raise ValueError(f"Isam2Settings: observe_every must be an integer ≥ 1, got {self.observe_every!r}")
        if self.lag_s is not None and not self.lag_s > 0:
            raise ValueError(f"Isam2Settings: lag_s must be None or > 0, got {self.lag_s!r}")
