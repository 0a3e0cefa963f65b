"""The smoother behind :class:`~stslam.graph.state.GraphState`: full iSAM2, or iSAM2 over a fixed lag (SPEC 14).

Both answer the same calls: ``update`` with new factors, variables and
factor indices to remove (returning the new factors' indices), a variable's
estimate and marginal covariance, and a joint marginal.

* :class:`FullSolver` is ``gtsam.ISAM2`` over the whole run: every pose and
  landmark state stays a variable to the end, so the final trajectory is the
  full smoothing solution.
* :class:`LagSolver` is ``gtsam.IncrementalFixedLagSmoother``: a variable is
  marginalised out once no factor has touched it for ``lag_s`` seconds. Where
  the graph grows by many variables per frame (Dyn. SLAM's velocity state of
  every point at every frame, an RGB-D sequence of hundreds of frames) the
  full tree's updates grow with the run; a window keeps them bounded. What
  leaves the window is remembered as it last was (estimate and marginal),
  so the final trajectory is the fixed-lag smoothed one: each pose as
  estimated ``lag_s`` after its own time.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Isam2Settings:
    """How the iSAM2 back end is run.

    Attributes
    ----------
    relinearize_threshold : float
        iSAM2's relinearisation threshold on a variable's update (units of the variable): on a pose's
        heading (rad) and on every landmark state but a static point's.
    relinearize_threshold_m : float
        The threshold on a pose's position and a static point's (m). Every factor is linear in these
        for a fixed heading (h = R(θ)ᵀ(m − t), odometry x' = x + R(θ)·d, SPEC 5.1, 5.2): a position's
        update changes only the heading's Jacobians, by δp·δθ (δθ below ``relinearize_threshold``), so
        the positions can wait for larger updates than the angles (:func:`key_letter`).
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
        iSAM2's elimination: Cholesky (faster) or QR (stabler on badly conditioned graphs).
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
    """

    relinearize_threshold: float = 0.01
    relinearize_threshold_m: float = 0.01
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

    def __post_init__(self):
        if self.structure not in ("fixed", "variable"):
            raise ValueError(f"Isam2Settings: structure must be fixed or variable, got {self.structure!r}")
        if self.factorization not in ("cholesky", "qr"):
            raise ValueError(f"Isam2Settings: factorization must be cholesky or qr, got {self.factorization!r}")
        if not (self.relinearize_threshold > 0 and self.relinearize_threshold_m > 0 and self.floor_sigma > 0
                and self.structure_sigma > 0):
            raise ValueError("Isam2Settings: relinearize_threshold, relinearize_threshold_m, floor_sigma and "
                             "structure_sigma must be > 0")
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


# A variable's key letter: "x" a pose, "s" a static point, else a letter from its dimension (1 … MAX_SIZE).
LETTERS = "bcdefghijklmnopqrtuvw"
MAX_SIZE = len(LETTERS)


def key_letter(block) -> str:
    """The symbol letter of a landmark variable of ``block`` (a block object, or a dimension): "s" for a
    static point, else one letter per dimension, so that iSAM2's per-letter relinearisation thresholds
    (a vector each, of the variable's dimension) fit every variable (:func:`_params`)."""
    from stslam.slam.blocks import StaticPointBlock

    if isinstance(block, StaticPointBlock):
        return "s"
    size = int(block) if isinstance(block, (int, np.integer)) else int(block.size)
    if not 1 <= size <= MAX_SIZE:
        raise ValueError(f"key_letter: a variable of 1 … {MAX_SIZE} dimensions, got {size}")
    return LETTERS[size - 1]


def _thresholds(settings):
    """iSAM2's relinearisation thresholds per key letter (Isam2Settings.relinearize_threshold_m)."""
    import gtsam

    angle, metres = settings.relinearize_threshold, settings.relinearize_threshold_m
    thresholds = gtsam.ISAM2ThresholdMap()
    thresholds.insert(("x", np.array([metres, metres, angle])))
    thresholds.insert(("s", np.full(3, metres)))
    for size, letter in enumerate(LETTERS, start=1):
        thresholds.insert((letter, np.full(size, angle)))
    return thresholds


def _params(settings, scheduled: bool = False):
    """iSAM2's parameters; ``scheduled``: relinearisation only where an update forces it (the caller's schedule)."""
    import gtsam

    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(_thresholds(settings))
    params.relinearizeSkip = settings.relinearize_skip
    params.enableRelinearization = not scheduled
    if settings.factorization == "qr":
        params.setFactorization("QR")
    return params


class FullSolver:
    """``gtsam.ISAM2`` over the whole run."""

    windowed = False

    def __init__(self, settings):
        import gtsam

        self._scheduled = settings.relinearize_frames is not None
        self._isam = gtsam.ISAM2(_params(settings, self._scheduled))
        self._skip = settings.relinearize_skip

    def update(self, graph, values, removals, time_s: float, keep=(), relinearize: bool = False) -> list:
        """Add factors and variables, remove factors; ``relinearize``: check relinearisation at this update
        (with ``relinearize_frames`` the only updates that do)."""
        result = self._isam.update(graph, values, removals, force_relinearize=relinearize and self._scheduled)
        return list(result.getNewFactorsIndices())

    def relinearize(self) -> int:
        """Empty iSAM2 updates up to and including the next relinearisation check (one every
        ``relinearize_skip`` updates, or the next one forced): every variable whose update exceeds its
        threshold is relinearised, as during the run; returns how many were."""
        for _ in range(1 if self._scheduled else self._skip):
            relinearized = int(self._isam.update(force_relinearize=self._scheduled).getVariablesRelinearized())
            if relinearized:
                return relinearized
        return 0

    def gone(self, key) -> tuple | None:
        """(estimate, covariance) of a variable no longer in the smoother, or None."""
        return None

    def holds(self, key) -> bool:
        """Whether the smoother holds variable ``key`` (iSAM2 drops one whose factors were all removed)."""
        return bool(self._isam.valueExists(key))

    def estimate(self, key) -> np.ndarray:
        return np.asarray(self._isam.calculateEstimateVector(key), dtype=float)

    def marginal(self, key) -> np.ndarray:
        return np.asarray(self._isam.marginalCovariance(key), dtype=float)

    def joint(self, keys) -> np.ndarray:
        import gtsam

        return np.asarray(self._isam.jointMarginalCovariance(gtsam.KeyVector(list(keys))).fullMatrix(), dtype=float)


class LagSolver(FullSolver):
    """``gtsam.IncrementalFixedLagSmoother`` with lag ``settings.lag_s`` (module docstring)."""

    windowed = True

    def __init__(self, settings):
        import gtsam

        self._lag = float(settings.lag_s)
        self._smoother = gtsam.IncrementalFixedLagSmoother(self._lag, _params(settings))
        self._touched: dict = {}  # key -> time (s) a factor last touched it
        self._gone: dict = {}  # key -> (estimate, covariance) when it left the window

    @property
    def _isam(self):
        return self._smoother.getISAM2()

    def update(self, graph, values, removals, time_s: float, keep=(), relinearize: bool = False) -> list:
        """As :meth:`FullSolver.update` (on the window's own relinearisation schedule); variables leaving the
        window are remembered, with their marginal when they are poses or in ``keep`` (the keys a later factor
        may still need)."""
        stamps = {}
        for i in range(graph.size()):
            for key in graph.at(i).keys():
                stamps[key] = time_s
        self._touched.update(stamps)
        leaving = [key for key, t in self._touched.items() if t < time_s - self._lag]
        for key in leaving:  # remembered as they are now, before they are marginalised out
            self._gone[key] = (self.estimate(key), self.marginal(key) if key in keep or _is_pose(key) else None)
            del self._touched[key]
        self._smoother.update(graph, values, stamps, removals)
        return list(self._smoother.getISAM2Result().getNewFactorsIndices())

    def relinearize(self) -> int:
        self._smoother.update()
        return 1  # the window's own schedule: nothing to stop on

    def gone(self, key) -> tuple | None:
        return self._gone.get(key)

    def estimate(self, key) -> np.ndarray:
        if key in self._gone:
            return self._gone[key][0]
        return np.asarray(self._smoother.calculateEstimateVector(key), dtype=float)

    def marginal(self, key) -> np.ndarray:
        if key in self._gone:
            return self._gone[key][1]
        return np.asarray(self._smoother.marginalCovariance(key), dtype=float)


def _is_pose(key) -> bool:
    import gtsam

    return gtsam.Symbol(key).chr() == ord("x")


def make_solver(settings):
    """The solver of ``settings`` (:class:`~stslam.graph.state.Isam2Settings`): windowed when ``lag_s`` is set."""
    return FullSolver(settings) if settings.lag_s is None else LagSolver(settings)
