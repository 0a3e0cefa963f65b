"""Online articulation model selection (SPEC 4, paper §IV, Algorithm 1).

Per landmark, a bank of per-model filters (:mod:`stslam.selection.model_filter`) scores
every model by the likelihood of its innovation, and the model probabilities
μ_j are updated in log space:

    threshold (Algorithm 1):  log μ_j(t) = log L_j + log μ_j(t−1) − log Σ_i L_i μ_i(t−1)
    imm:                      log μ⁻_j  = log Σ_i Π_ij μ_i(t−1)        (Markov prediction)
                              log μ_j(t) = log L_j + log μ⁻_j − log Σ_i L_i μ⁻_i

with L_j = N(y_j; 0, S_j). The model is chosen the first time some μ_j > τ
(Algorithm 1) *and the observations support it* (:meth:`ModelSelector.supported`):

* static only while the track has not moved significantly (p > ``static_alpha``);
* prismatic or revolute only once it has (p < ``support_alpha``), and revolute
  only once its fit window supports a curvature (F-test at ``support_alpha``)
  (tests: :mod:`stslam.articulation.evidence`).

Why the guards, measured (nested models' early likelihood ratios are small and noisy), the guards for
real tracks (``min_motion_m``, ``hold_steps``), ``revise``, ``nested_price``, ``outlier_nis``: docs/selection.md.

Structures are refitted on the growing window of past observations on a schedule (SPEC 6.3(b),
:mod:`stslam.selection.schedule`); each likelihood still scores an observation the structure has
not seen, so μ remains a product of one-step predictive probabilities.

Conventions, written once:

* Markov matrix Π: **rows = from, columns = to**; Π_ij = P(model j at t |
  model i at t−1), rows sum to one.
* Probabilities are floored at ``MIN_LOG_MU`` (the smallest normal float) so a
  model far off never reaches exactly 0 and can come back; a model whose
  structure cannot be fitted (SPEC 2.4) has μ = 0 exactly (log μ = −inf) and
  the reason is kept.
* Step indices are 0-based observation indices of the track.

The IMM variant is a *switching-probability* IMM: the models' state spaces
differ, so estimates are not mixed; only the probabilities pass through the
Markov chain, and a model that has lost can win again (docs/selection.md).
"""

from __future__ import annotations

import math

import numpy as np

from stslam.articulation.models import get_model
from stslam.errors import DegenerateFitError
from stslam.selection.decision import DecisionRecord, DecisionViews, decision_log_probabilities
from stslam.selection.bank import FilterBank
from stslam.selection.model_filter import ModelFilter
from stslam.selection.nested_price import WindowPrice
from stslam.selection.schedule import RefitSchedule, judged_models, quiet_refit
from stslam.selection.rest import RestingFits
from stslam.selection.views import TrackViews
from stslam.selection.probabilities import (MIN_LOG_MU, first_argmax_mismatch, imm_prior, imm_update,  # noqa: F401
                                        logsumexp, markov_matrix, normalise_log, threshold_update)
from stslam.selection.settings import SelectionSettings
from stslam.articulation.evidence import MotionStatistics, circle_support, noise_variance
from stslam.selection.observation_covariance import ObservationCovariances

# With ``outlier_nis``: at most this many observations in a row are skipped; a longer run is
# the track itself (a jump of the marker, or motion no filter predicted) and is taken.
OUTLIER_RUN = 3

class ModelSelector(DecisionViews, TrackViews):
    """Articulation model selection for one point track, one observation at a time.

    Usable online (call :meth:`observe` for each new point, e.g. inside SLAM)
    or offline (:func:`select_track` over a whole track).

    Parameters: ``settings`` (SelectionSettings).

    Attributes
    ----------
    names : tuple[str, ...]
        Model names, in the order of every μ vector.
    failures : dict[str, str]
        Model name → why its structure could not be fitted (its μ is 0).
    chosen, chosen_step : str or None, int or None
        The model chosen the first time some μ_j > τ (after the motion gate), and its observation index.
    start_step : int or None
        Observation index at which the structures were first fitted.
    unsupported : dict[str, str or None]
        Model name → why its latest fit window does not support it (None if it does;
        prismatic and revolute, by the curvature F-test, :meth:`supported`).
    schedule, price_schedule : stslam.selection.schedule.RefitSchedule
        When the structures, and the nested price, are refitted.
    settled : bool
        Whether the filter bank has stopped (``settle_steps``, docs/selection.md §5).
    quiet : bool
        Whether the bank and the structure refits rest while static holds (``quiet_static``, docs/selection.md §7).
    """

    def __init__(self, settings: SelectionSettings):
        self.settings = settings
        self.names = tuple(settings.models)
        models = [get_model(name, **settings.model_options.get(name, {})) for name in self.names]
        self.filters = [ModelFilter(m, settings.filters[m.name]) for m in models]
        self._bank = FilterBank(self.filters)
        self._all_rows = tuple(range(len(self.filters)))
        self._transition = markov_matrix(len(self.names), settings.stay_probability)
        with np.errstate(divide="ignore"):
            self._log_transition = np.log(self._transition)
        self._log_tau, self._log_not_tau = np.log(settings.tau), math.log1p(-settings.tau)
        self._static = self.names.index("static") if "static" in self.names else None
        self._noise_var = (None, None)  # (generations of the filters' fits, σ̂² of motion_p_value)
        self._points: list[np.ndarray] = []
        self._dts: list[float] = []
        self._fit_points, self._log_mu_rows = [], []  # list[np.ndarray]: thinned points, log μ per step
        self.log_mu = None
        self.failures: dict[str, str] = {}
        self._unsupported: dict[str, str | None] = {}
        self._support_test = None  # the latest circle fit's curvature test, until read (see unsupported)
        self._motion, self._time = MotionStatistics(), 0.0
        self.decisions = DecisionRecord(settings.hold_steps, settings.revise)
        self._price = None if settings.nested_price is None else WindowPrice(settings.measurement_sigma_m,
                                                                             settings.nested_price)
        self._carry_dt, self._skipped, self.settled, self._moving_run = 0.0, 0, False, 0
        self.quiet, self._resting = False, RestingFits()  # quiet_static (docs/selection.md §7)
        self._decision = (None, None, None)  # (log μ, log B, decision_log_mu()) of the latest call
        self.start_step, self._reference, self._extent_m = None, None, 0.0
        self.schedule, self.price_schedule = (RefitSchedule(
            settings.refit_growth, settings.refit_dense_until, settings.refit_extent_floor_m,
            settings.measurement_sigma_m, settings.refit_converged) for _ in range(2))  # structures, nested price
        self.last_log_likelihood = None
        self._covs = ObservationCovariances(settings.measurement_sigma_m)  # observe's ``cov``

    # -- observations ----------------------------------------------------------------
    @property
    def n_observations(self) -> int:
        return len(self._points)

    @property
    def moved_m(self) -> float:
        """Largest distance (m) of any observation from the mean of the first N_min."""
        return self._extent_m

    def observe(self, z_world, dt: float | None = None, cov=None) -> np.ndarray | None:
        """Take one observed point (3,) (m, world frame) ``dt`` after the previous one, with its own
        covariance ``cov`` (3, 3) (m², :mod:`stslam.selection.observation_covariance`) if given.

        Returns the current μ (r,) or None before selection has started.
        """
        z = np.asarray(z_world, dtype=float).reshape(-1)
        if z.shape != (3,) or not all(map(math.isfinite, z.tolist())):
            raise ValueError(f"an observation must be 3 finite numbers (m), got {z_world!r}")
        dt = self.settings.dt if dt is None else float(dt)
        if not dt > 0:
            raise ValueError(f"dt must be > 0, got {dt!r}")
        t = len(self._points)
        self._covs.add(cov, t)
        if self.log_mu is None:
            self._add(z, dt)
            if len(self._points) >= self.settings.n_min:
                self._start()
        elif self.settled:  # the filters' work is done: only the nested price can still change
            self._track_extent(z)
            self._add(z, dt)
            self._maybe_refit()
        else:
            self._track_extent(z)
            self._maybe_refit()
            self._add(z, dt)
            if not self.quiet:
                self._step(z, dt, cov)
            elif self.motion_p_value() < self.settings.support_alpha:
                self.wake()  # quiet_static: the point may have moved
        self._log_mu_rows.append(np.full(len(self.names), np.nan) if self.log_mu is None
                                 else self.log_mu.copy())
        self._decide(t)
        if (self.settings.quiet_static and self.log_mu is not None and not (self.settled or self.quiet)
                and self.decisions.held == "static" and self.motion_p_value() >= self.settings.support_alpha):
            self.quiet = True  # no moving model can be declared before the motion test rejects
            self._resting.begin(len(self._points))
        return None if self.log_mu is None else np.exp(self.log_mu)

    def _add(self, z: np.ndarray, dt: float) -> None:
        self._time += dt if self._points else 0.0
        if self._covs.matrices is None:  # with covariances, their weighted sums answer the motion test
            self._motion.add(self._time, z)
        self._points.append(z)
        self._dts.append(dt)
        spacing = self.settings.fit_spacing_m
        if not self._fit_points or _distance(z, self._fit_points[-1]) >= spacing:
            self._fit_points.append(z)

    def _fit_window(self) -> np.ndarray:
        """Points the structures are fitted on: thinned, but never fewer than N_min (latest raw ones)."""
        if len(self._fit_points) >= self.settings.n_min:
            return np.array(self._fit_points)
        return np.array(self._points[-self.settings.n_min:])

    def _start(self) -> None:
        """Fit every structure on the window and set μ_j = 1/r over applicable models (SPEC 4)."""
        window = np.array(self._points)
        fit_window = self._fit_window()
        log_mu = np.zeros(len(self.names))
        for j, f in enumerate(self.filters):
            try:
                f.start(window, self._dts, fit_window, self._covs.matrices)
                self.failures.pop(f.name, None)
                self._test_support(f, fit_window)
            except DegenerateFitError as error:
                self.failures[f.name] = str(error)
                log_mu[j] = -np.inf
        if not np.isfinite(log_mu).any():
            return  # no model applicable yet: try again with the next observation
        self.log_mu = normalise_log(log_mu)
        self.start_step = len(self._points) - 1
        self._reference = window.mean(axis=0)
        self._extent_m = float(np.max(np.linalg.norm(window - self._reference, axis=1)))
        self.schedule.start(len(window), self._extent_m)
        self.price_schedule.start(len(window), self._extent_m)

    def _track_extent(self, z: np.ndarray) -> None:
        self._extent_m = max(self._extent_m, _distance(z, self._reference))

    def wake(self) -> None:
        """``quiet_static`` (docs/selection.md §7): if resting, the bank steps through the observations it rested
        over now, with the refits their schedule made, as it would have without resting (done when the motion
        test rejects, or when a caller needs the decisions of the real μ)."""
        if not self.quiet:
            return
        self.quiet = False
        start, refits = self._resting.end()
        covs = self._covs.matrices
        for i in range(start, len(self._points)):
            if i in refits:
                self._refit(self._points[:i], self._dts[:i], *refits[i])  # with the structures fitted resting
            self._step(self._points[i], self._dts[i], None if covs is None else covs[i])

    def _maybe_refit(self) -> None:
        """Refit structures and the nested price on their schedules (SPEC 6.3(b), :mod:`stslam.selection.schedule`)."""
        s, n, extent = self.settings, len(self._points), self._extent_m
        if s.refit and self._price is not None and self.price_schedule.due(n, extent):
            self._price.refit(self._fit_window())  # the price of the nested models has its own schedule
            self.price_schedule.done(n, extent, s.refit_converged and self.settled and self._price.quiet())
        if not s.refit or self.settled or not self.schedule.due(n, extent):
            return  # settled: only the price can still change (see _decide)
        if self.quiet:  # resting: only the fits the motion test reads (stslam.selection.rest)
            self._resting.refit(self.filters, self._fit_window(), self.log_mu, s.selector, n, s.measurement_sigma_m)
            return self.schedule.done(n, extent, False)
        self.schedule.done(n, extent, self._refit(self._points, self._dts, self._fit_window()))

    def _refit(self, points: list, dts: list, fit_window: np.ndarray, fitted: dict | None = None) -> bool:
        """Refit every applicable structure on ``fit_window`` (``fitted``: model name → a structure already fitted
        on it) and filter the tail of ``points`` with it; returns whether the refit was quiet
        (``refit_converged``, :func:`stslam.selection.schedule.quiet_refit`)."""
        s = self.settings
        old = [f.structure for f in self.filters]
        prepared = {}
        for j, f in enumerate(self.filters):
            if not np.isfinite(self.log_mu[j]) and s.selector == "threshold":
                continue  # μ = 0 stays 0 under Bayes' rule: no need to refit
            try:
                prepared[j] = f.prepare(points, dts, fit_window, None if fitted is None else fitted.get(f.name))
            except DegenerateFitError as error:
                if not np.isfinite(self.log_mu[j]):
                    self.failures[f.name] = str(error)
        for first in sorted(set(prepared.values())):  # the bank filters the rest of the window
            rows = [j for j, i in prepared.items() if i == first]
            for j in self._bank.rerun(rows, points, dts, first, self._covs.matrices):
                f = self.filters[j]
                f.restore_previous()
                try:  # again one by one, for the same state and message as a failed start
                    f.start(points, dts, fit_window, self._covs.matrices)
                except DegenerateFitError as error:
                    if not np.isfinite(self.log_mu[j]):
                        self.failures[f.name] = str(error)
                    del prepared[j]
        for j, f in enumerate(self.filters):
            if j not in prepared:
                continue  # keep the previous structure of an applicable model
            self._test_support(f, fit_window)
            if not np.isfinite(self.log_mu[j]):  # imm: a model fittable at last joins the chain
                self.failures.pop(f.name, None)
                self.log_mu[j] = MIN_LOG_MU
        self.log_mu = normalise_log(self.log_mu)
        return s.refit_converged and quiet_refit(old, self.filters, fit_window, s.measurement_sigma_m, set(prepared)
                                                 & judged_models(self.names, self.log_mu, self.supported, self._price))

    def _step(self, z: np.ndarray, dt: float, cov=None) -> None:
        """Predict, score and update every applicable filter, then update μ (SPEC 4)."""
        gate = self.settings.outlier_nis
        saved = [f.snapshot() for f in self.filters] if gate is not None else None
        dt = dt + self._carry_dt
        alive = np.isfinite(self.log_mu)
        if alive.all():  # every model applicable: the bank's row order is the models'
            log_lik, nis, _ = self._bank.step(self._all_rows, z, dt, cov)  # a broken structure explains nothing
            log_lik = log_lik.copy()
        else:
            log_lik = np.full(len(self.names), -np.inf)
            rows = np.flatnonzero(alive)
            log_lik[rows], nis, _ = self._bank.step(rows, z, dt, cov)
        if gate is not None and min(nis) > gate and self._skipped < OUTLIER_RUN:  # an outlier (docs/selection.md §4)
            for f, snapshot in zip(self.filters, saved, strict=True):
                f.restore(snapshot)
            self._carry_dt, self._skipped = dt, self._skipped + 1
            return
        self._carry_dt, self._skipped = 0.0, 0
        self.last_log_likelihood = log_lik.copy()
        log_lik[~alive] = 0.0  # unused: μ_j = 0 stays 0
        if self.settings.selector == "imm":
            self.log_mu = imm_update(self.log_mu, log_lik, self._transition, self._log_transition)
        else:
            self.log_mu = threshold_update(self.log_mu, log_lik)

    def _decide(self, t: int) -> None:
        """Algorithm 1's test μ_j > τ for a supported model, after the motion gate, held for ``hold_steps`` steps."""
        current = None
        if self.log_mu is not None and self._extent_m >= self.settings.min_motion_m:
            log_p = self.decision_log_mu()
            j = int(log_p.argmax())
            if log_p[j] > self._log_tau and self.supported(self.names[j]):
                current = self.names[j]
        self.decisions.add(t, current)
        s = self.settings
        if (s.settle_steps is not None and s.nested_price is not None and self._static is not None
                and self.log_mu is not None and not self.settled):
            # the bank's question, moving or resting, is answered: static is ruled out and μ_static < 1 − τ
            moving = (self._extent_m >= s.min_motion_m and self.log_mu[self._static] < self._log_not_tau
                      and not self.supported("static"))
            self._moving_run = self._moving_run + 1 if moving else 0
            self.settled = self._moving_run >= s.settle_steps  # prismatic vs revolute is then B's call

    @property
    def log_bayes_factor(self) -> float | None:
        """log B, revolute : prismatic, of the latest fit window (docs/selection.md §2); None without a price."""
        return None if self._price is None else self._price.log_bayes_factor

    def decision_log_mu(self) -> np.ndarray:
        """log of the decision probabilities: μ, or μ with the nested price (:mod:`stslam.selection.decision`)."""
        key = (self.log_mu, self.log_bayes_factor)  # a new μ is a new array: the same one was not changed
        if self._decision[0] is not key[0] or self._decision[1] != key[1]:
            self._decision = (*key, decision_log_probabilities(self.names, *key))
        return self._decision[2]

    def _test_support(self, f: ModelFilter, fit_window: np.ndarray) -> None:
        """After a fit: does the window support a circle? (kept until the next fit; tested when first read,
        with the noise floor of the fit's time: the decisions ask only while a moving model leads)."""
        alpha, price = self.settings.support_alpha, self.settings.nested_price
        if f.name == "revolute" and price is None and alpha is not None:
            self._support_test = (fit_window, f.structure.residual_m, self._covs.sigma_floor_m, alpha)

    @property
    def unsupported(self) -> dict[str, str | None]:
        """Model name → why the latest fit window does not support it, or None (class docstring)."""
        if self._support_test is not None:
            reason = circle_support(*self._support_test)
            self._support_test = None
            self._unsupported["revolute"] = reason
            # The same F-test read the other way: a window whose curvature is significant is no line.
            self._unsupported["prismatic"] = None if reason is not None else "the window's curvature is significant"
        return self._unsupported

    def motion_p_value(self) -> float:
        """p-value of "the point has not moved" so far (evidence.motion_p_value; σ̂² of the line and circle fits)."""
        key = (tuple(f.generation for f in self.filters), self._resting.version)
        if self._noise_var[0] != key:  # σ̂² changes with the fits only
            fits = self._resting.noise_fits(self.filters)
            self._noise_var = (key, noise_variance(fits, self.settings.measurement_sigma_m))
        return self._covs.motion_p_value(self._motion, self._points, self._dts, self._noise_var[1])

    def supported(self, name: str) -> bool:
        """Whether the observations so far support declaring model ``name`` (decision guard).

        static: the track has not moved significantly (p > ``static_alpha``); prismatic: it has
        (p < ``support_alpha``), and the latest fit window does not show a significant curvature;
        revolute: it has, and that window does show one (F-test at ``support_alpha``). None: off.
        """
        s = self.settings
        if name == "static":
            return s.static_alpha is None or self.motion_p_value() > s.static_alpha
        if s.support_alpha is None:
            return True
        if s.nested_price is None and self.unsupported.get(name) is not None:
            return False  # with a nested price, the Bayes factor takes the curvature test's place
        return self.motion_p_value() < s.support_alpha


def _distance(a: np.ndarray, b: np.ndarray) -> float:
    """‖a − b‖ of two points (3,): √(d·d), d = a − b, on Python floats (numpy's calls cost more than the sum)."""
    (a0, a1, a2), (b0, b1, b2) = a.tolist(), b.tolist()
    d0, d1, d2 = a0 - b0, a1 - b1, a2 - b2
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


def select_track(points_world, settings: SelectionSettings, times_s=None) -> ModelSelector:
    """Run selection over a whole track (n, 3) (offline); ``times_s`` (n,) sets each δt (else ``settings.dt``)."""
    points = np.asarray(points_world, dtype=float)
    selector = ModelSelector(settings)
    dts = None if times_s is None else np.diff(np.asarray(times_s, dtype=float), prepend=np.nan)
    for i, z in enumerate(points):
        selector.observe(z, None if dts is None or i == 0 else dts[i])
    return selector
