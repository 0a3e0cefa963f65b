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

import re
from dataclasses import replace

import numpy as np

from stslam.graph import factors
from stslam.graph.reread import LOOSE_SIGMA
from stslam.graph.settings import Isam2Settings

__all__ = ["FullSolver", "Isam2Settings", "LagSolver", "key_letter", "make_solver"]

# A variable's key letter: "x" a pose, "s" a static point, "y" a constant-velocity point, else a letter from its
# dimension (1 … MAX_SIZE), upper case for the motion state of a one-dof articulated landmark (q first).
LETTERS = "bcdefghijklmnopqrtuvw"
MAX_SIZE = len(LETTERS)


def key_letter(block) -> str:
    """The symbol letter of a landmark variable of ``block`` (a block object, or a dimension): "s" for a
    static point, "y" for a constant-velocity point (Dyn. SLAM's), an upper-case letter per dimension for an
    articulated block of one degree of freedom (q first: Isam2Settings.relinearize_threshold_q), else a lower-case
    one per dimension, so that iSAM2's per-letter relinearisation thresholds (a vector each, of the variable's
    dimension) fit every variable (:func:`_params`)."""
    from stslam.slam.blocks import ConstantVelocityPointBlock, StaticPointBlock

    if isinstance(block, StaticPointBlock):
        return "s"
    if isinstance(block, ConstantVelocityPointBlock):
        return "y"
    size = int(block) if isinstance(block, (int, np.integer)) else int(block.size)
    if not 1 <= size <= MAX_SIZE:
        raise ValueError(f"key_letter: a variable of 1 … {MAX_SIZE} dimensions, got {size}")
    one_dof = not isinstance(block, (int, np.integer)) and hasattr(block, "motion_size") and block.dof == 1
    return LETTERS[size - 1].upper() if one_dof else LETTERS[size - 1]


def threshold_vectors(settings) -> dict:
    """iSAM2's relinearisation threshold per key letter (:func:`key_letter`; Isam2Settings.relinearize_threshold,
    _m, _q): a vector of the variable's dimension each. A pose's position, a static point and a constant-velocity
    point's position and velocity (m, m/s) take ``relinearize_threshold_m``: every factor on them is linear in
    them for fixed headings (:class:`~stslam.graph.settings.Isam2Settings`)."""
    angle, metres = settings.relinearize_threshold, settings.relinearize_threshold_m
    q = angle if settings.relinearize_threshold_q is None else settings.relinearize_threshold_q
    vectors = {"x": np.array([metres, metres, angle]), "s": np.full(3, metres), "y": np.full(6, metres)}
    for size, letter in enumerate(LETTERS, start=1):
        vectors[letter] = np.full(size, angle)
        vectors[letter.upper()] = np.r_[q, np.full(size - 1, angle)]
    return vectors


def _thresholds(settings):
    """:func:`threshold_vectors` as gtsam's map."""
    import gtsam

    thresholds = gtsam.ISAM2ThresholdMap()
    for letter, vector in threshold_vectors(settings).items():
        thresholds.insert((letter, vector))
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


MAX_ANCHORS = 20  # loose priors one rebuild may add to variables the graph leaves undetermined (FullSolver)


def _indeterminate_key(error: Exception) -> int | None:
    """The variable an indeterminate elimination names ("... near variable <key> ..."), or None."""
    match = re.search(r"variable\s+(\d+)", str(error)) if _indeterminate(error) else None
    return int(match.group(1)) if match else None


def _indeterminate(error: Exception) -> bool:
    """Whether ``error`` is gtsam's IndeterminantLinearSystemException (a RuntimeError in Python): an elimination
    met a variable whose information block is not positive definite (under Cholesky also one that is, but whose
    Hessian, the square of the Jacobian's conditioning, rounds to singular)."""
    return isinstance(error, RuntimeError) and "Indeterminate linear system" in str(error)


class FullSolver:
    """``gtsam.ISAM2`` over the whole run.

    Under Cholesky, an update or a marginal that gtsam finds indeterminate is not the end of the run: the
    iSAM2 object is rebuilt under QR from the graph and the linearisation point it holds (the failed update's
    factors and variables included: gtsam takes them in before it eliminates), and the run stays on QR
    (``fallbacks`` counts the rebuilds). Where QR too finds a variable undetermined, that variable gets a
    loose prior (σ = ``LOOSE_SIGMA`` at its estimate, :func:`stslam.graph.factors.loose_prior_factor`) and the
    rebuild is tried again, at most ``MAX_ANCHORS`` times (``anchors`` counts them): kitchen tuning seed 1002
    left two motion-state variables of a landmark tied only to each other, a pair nothing places, and the run
    ended there. A loose prior on such a pair changes no other estimate. Factor indices are the solver's own,
    kept across a rebuild.
    """

    windowed = False
    _recovers = True  # a failed Cholesky elimination rebuilds under QR (LagSolver: not)

    def __init__(self, settings):
        import gtsam

        self._settings = settings
        self._scheduled = settings.relinearize_frames is not None
        self._isam = gtsam.ISAM2(_params(settings, self._scheduled))
        self._skip = settings.relinearize_skip
        self.fallbacks = self.anchors = 0
        self._slots: list | None = None  # after a rebuild: the solver's factor index -> iSAM2's (None: removed)

    def _recoverable(self, error: Exception) -> bool:
        return self._recovers and _indeterminate(error)

    def _guarded(self, call):
        """``call()``, again after a rebuild under QR if it fails as :meth:`_recoverable`."""
        try:
            return call()
        except RuntimeError as error:
            if not self._recoverable(error):
                raise
        self._rebuild()
        return call()

    def _rebuild(self) -> None:
        """A new iSAM2 under QR on the current one's factors (removed ones left out) at its linearisation point:
        the same linear system, eliminated afresh (so the estimate is the one its update would have given)."""
        import gtsam

        held, theta = self._isam.getFactorsUnsafe(), self._isam.getLinearizationPoint()
        graph, moved = gtsam.NonlinearFactorGraph(), {}
        for i in range(held.size()):
            factor = held.at(i)
            if factor is not None:
                moved[i] = graph.size()
                graph.add(factor)
        used = set(graph.keyVector())
        values, keys = gtsam.Values(theta), theta.keys()
        for key in keys:
            if key not in used:  # iSAM2 drops a variable whose factors were all removed (holds)
                values.erase(key)
        self._settings = replace(self._settings, factorization="qr")
        for attempt in range(MAX_ANCHORS + 1):
            isam = gtsam.ISAM2(_params(self._settings, self._scheduled))
            try:
                isam.update(graph, values)
                break
            except RuntimeError as error:  # a variable QR cannot place either: anchor it loosely (class docstring)
                key = _indeterminate_key(error)
                if key is None or attempt == MAX_ANCHORS or not values.exists(key):
                    raise
                graph.add(factors.loose_prior_factor(key, values.atVector(key), LOOSE_SIGMA))
                self.anchors += 1
        slots = range(held.size()) if self._slots is None else self._slots
        self._slots = [None if slot is None else moved.get(slot) for slot in slots]
        self._isam = isam
        self.fallbacks += 1

    def update(self, graph, values, removals, time_s: float, keep=(), relinearize: bool = False) -> list:
        """Add factors and variables, remove factors; ``relinearize``: check relinearisation at this update
        (with ``relinearize_frames`` the only updates that do). Returns the new factors' indices."""
        removals = list(removals) if self._slots is None else [self._slots[i] for i in removals]
        try:
            result = self._isam.update(graph, values, removals, force_relinearize=relinearize and self._scheduled)
            new = list(result.getNewFactorsIndices())
        except RuntimeError as error:
            if not self._recoverable(error):
                raise
            return self._rebuild_after(graph, error)
        if self._slots is None:
            return new
        ours = list(range(len(self._slots), len(self._slots) + len(new)))
        self._slots.extend(new)
        return ours

    def _rebuild_after(self, graph, error: Exception) -> list:
        """Rebuild under QR after an update that failed in its elimination; returns its factors' indices. gtsam
        appends an update's factors to its graph before it eliminates: they are the last ``graph.size()``."""
        held, n = self._isam.getFactorsUnsafe(), graph.size()
        first = held.size() - n
        if first < 0 or any(held.at(first + j) is None or list(held.at(first + j).keys()) != list(graph.at(j).keys())
                            for j in range(n)):
            raise error  # not the state this recovery knows
        if self._slots is None:
            self._slots = list(range(first))
        ours = list(range(len(self._slots), len(self._slots) + n))
        self._slots.extend(range(first, first + n))
        self._rebuild()
        return ours

    def relinearize(self) -> int:
        """Empty iSAM2 updates up to and including the next relinearisation check (one every
        ``relinearize_skip`` updates, or the next one forced): every variable whose update exceeds its
        threshold is relinearised, as during the run; returns how many were."""
        for _ in range(1 if self._scheduled else self._skip):
            relinearized = self._guarded(lambda: int(self._isam.update(
                force_relinearize=self._scheduled).getVariablesRelinearized()))
            if relinearized:
                return relinearized
        return 0

    def gone(self, key) -> tuple | None:
        """(estimate, covariance) of a variable no longer in the smoother, or None."""
        return None

    def holds(self, key) -> bool:
        """Whether the smoother holds variable ``key`` (iSAM2 drops one whose factors were all removed)."""
        return bool(self._isam.valueExists(key))

    def factor_keys(self, index) -> list:
        """The keys of the factor the solver numbered ``index`` ([] once removed)."""
        slot = index if self._slots is None else self._slots[index]
        factor = None if slot is None else self._isam.getFactorsUnsafe().at(slot)
        return [] if factor is None else list(factor.keys())

    def estimate(self, key) -> np.ndarray:
        return np.asarray(self._guarded(lambda: self._isam.calculateEstimateVector(key)), dtype=float)

    def marginal(self, key) -> np.ndarray:
        return np.asarray(self._guarded(lambda: self._isam.marginalCovariance(key)), dtype=float)

    def joint(self, keys) -> np.ndarray:
        import gtsam

        keys = gtsam.KeyVector(list(keys))
        return np.asarray(self._guarded(lambda: self._isam.jointMarginalCovariance(keys).fullMatrix()), dtype=float)


class LagSolver(FullSolver):
    """``gtsam.IncrementalFixedLagSmoother`` with lag ``settings.lag_s`` (module docstring); no fallback to QR
    (the smoother's iSAM2 is its own), so a failed elimination under Cholesky ends the run."""

    windowed = True
    _recovers = False

    def __init__(self, settings):
        import gtsam

        self._settings, self.fallbacks, self._slots = settings, 0, None
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
    """The solver of ``settings`` (:class:`~stslam.graph.settings.Isam2Settings`): windowed when ``lag_s`` is set."""
    return FullSolver(settings) if settings.lag_s is None else LagSolver(settings)
