"""One predict/update of a bank of model filters at once (SPEC 3, SPEC 4).

Every step of online selection predicts and updates each model's filter
(:class:`~stslam.selection.model_filter.ModelFilter`) with the same point and
time step. When the filters share the temporal order, have one motion
variable (dof 1) and use the isotropic update (``fast_update`` with
``structure_uncertainty = "inflation"``), their states stack into X (r, k+1)
and P (r, k+1, k+1), and the whole bank is one sequence of array operations:

    X⁻ = F X,   P⁻ = F P Fᵀ + Q_j,   q⁻ = [1, 0, …] X⁻            (SPEC 3)
    z_j* = f_j(C_j, q⁻_j),   j_j = ∂f_j/∂q,   y_j = z − z_j*      (SPEC 2)
    M_j = ρ_j + P⁻_00 |j_j|²,  then the update of
    :func:`stslam.kalman.isotropic.isotropic_update` for d = 1, row by row.

Each row is computed with the same floating-point operations, in the same
order, as :meth:`ModelFilter.step` (stacked matrix products run the same
BLAS kernel on each matrix, element-wise operations are the same IEEE
operations), so the bank's states, likelihoods and NIS are those of the
filters stepped one by one, bit for bit. Banks that do not meet the
conditions step their filters one by one.
"""

from __future__ import annotations

import math

import numpy as np

from stslam.articulation.models import PrismaticModel, RevoluteModel, StaticModel
from stslam.kalman.ekf import LOG_2PI, MIN_LOG_LIKELIHOOD, InnovationCovarianceError, Update
from stslam.selection.initial_state import step_matrices
from stslam.selection.scalar_rows import KINDS, pack, rerun_rows, step_rows

ONES3 = np.ones(3)
_NO_WHITENING = np.zeros((3, 3))  # L⁻¹ argument of an unwhitened step (unused)
NOISES_KEPT = 16  # δt whose process noises a bank keeps per fit (a track's gaps come in a few sizes)
WHITENINGS_KEPT = 64  # covariances whose whitening a bank keeps: more than a rerun's window of points


def _point_static(structure, q):
    """StaticModel.position and .jacobian (paper perturbation) at one q (1,): P0 + l·[1,1,1], [1,1,1]."""
    return structure.p0 + q[0] * ONES3, ONES3


def _point_prismatic(structure, q):
    """PrismaticModel.position and .jacobian at one q (1,): P0 + l·n̂, n̂."""
    return structure.p0 + q[0] * structure.direction, structure.direction


def _point_revolute(structure, q):
    """RevoluteModel.position and .jacobian at one q (1,), sharing cos φ and sin φ (SPEC 2.3)."""
    phi = float(q[0])
    c, s = np.cos(phi), np.sin(phi)
    x0, y0 = structure.centre_xy
    r = structure.radius
    z = (x0 + r * c) * structure.v1 + (y0 + r * s) * structure.v2 + structure.p0
    return z, r * (-s * structure.v1 + c * structure.v2)


def _point_generic(model):
    def point(structure, q):
        return model.position(structure, q), model.jacobian(structure, q)[:, 0]
    return point


def point_function(model):
    """(z*, ∂f/∂q as (3,)) of a dof-1 model at one q (1,): the model's own formulas, evaluated once."""
    if type(model) is StaticModel and model.dof == 1:
        return _point_static
    if type(model) is PrismaticModel:
        return _point_prismatic
    if type(model) is RevoluteModel:
        return _point_revolute
    return _point_generic(model)


class BankStep:
    """The result of one stacked step: per row, what :class:`~stslam.kalman.ekf.Update` holds (built on demand)."""

    __slots__ = ("x", "P", "y", "a", "j", "rho", "log_likelihood", "nis", "cov")

    def __init__(self, x, P, y, a, j, rho, log_likelihood, nis, cov=None):
        self.x, self.P, self.y, self.a, self.j, self.rho = x, P, y, a, j, rho
        self.log_likelihood, self.nis = log_likelihood, nis
        self.cov = cov  # the point's own covariance C (R = ρC), or None (R = ρI)

    def update(self, i: int) -> Update:
        """Row i as the Update of :func:`stslam.kalman.isotropic.isotropic_update` (S = a·j jᵀ + ρI, or + ρC)."""
        j, rho = np.asarray(self.j[i], dtype=float), float(self.rho[i])
        S = float(self.a[i]) * np.outer(j, j) + rho * (np.eye(3) if self.cov is None else self.cov)
        return Update(self.x[i], self.P[i], np.asarray(self.y[i], dtype=float), S, self.log_likelihood[i],
                      float(self.nis[i]))


class FilterBank:
    """The model filters of one selector, stepped together when they can be (module docstring).

    Parameters
    ----------
    filters : list of ModelFilter
    """

    def __init__(self, filters):
        self.filters = list(filters)
        order = {f.settings.order for f in self.filters}
        self.stacked = len(order) == 1 and all(
            f.settings.fast_update and f.settings.structure_uncertainty == "inflation" and f.model.dof == 1
            for f in self.filters)
        self._points = [point_function(f.model) for f in self.filters] if self.stacked else None
        # order 1 with the three paper models: the rows' element-wise algebra on Python floats
        self.scalar = self.stacked and order == {1} and all(type(f.model) in KINDS for f in self.filters)
        self._kinds = np.array([KINDS[type(f.model)] for f in self.filters]) if self.scalar else None
        self._constants = {}  # row → (generation, the structure's packed numbers, scalar_rows.pack)
        self._state = None  # (rows, X, P, x views, P views): the stacked arrays the rows' x, P are views of
        self._structures = None  # ((rows, their fits' generations), kinds (r,), packed (r, 12))
        self._noise = None  # ((rows, their fits' generations), δt → _stacked_noise's terms)
        self._whitenings = {}  # id(C) → (C, _whitening(C)) of the latest points' covariances

    # ------------------------------------------------------------------ stacked arrays
    def _stacked_state(self, rows: tuple[int, ...]):
        """The rows' x and P stacked: the previous step's arrays while the filters still hold its row views."""
        state = self._state
        if state is not None and state[0] == rows:
            _, X, P, xs, Ps = state
            if all(self.filters[j].x is xs[i] and self.filters[j].P is Ps[i] for i, j in enumerate(rows)):
                return X, P
        return (np.array([self.filters[j].x for j in rows]), np.array([self.filters[j].P for j in rows]))

    def _stacked_noise(self, rows: tuple[int, ...], dt: float):
        """(Q (r, n, n), ρ, 2 log ρ, ρ and 2 log ρ of a whitened point (r,)) of the rows at δt, kept per δt
        while the rows' fits stay."""
        key = (rows, tuple(self.filters[j].generation for j in rows))
        if self._noise is None or self._noise[0] != key:
            self._noise = (key, {})
        per_dt = self._noise[1]
        terms = per_dt.get(dt)
        if terms is None:
            fs = [self.filters[j] for j in rows]
            Q = np.array([step_matrices(f.settings.order, 1, dt, f.motion.sigma_eta)[1] for f in fs])
            rho = np.array([float(f.R[0, 0]) for f in fs])
            # R = (R₀₀/σ_z²)·C for a point with its own C (ModelFilter.step): after whitening by C, ρ I
            scale = np.array([float(f.R[0, 0]) / f.settings.measurement_sigma_m ** 2 for f in fs])
            terms = per_dt[dt] = (Q, rho, 2.0 * np.log(rho), scale, 2.0 * np.log(scale))
            if len(per_dt) > NOISES_KEPT:
                del per_dt[next(iter(per_dt))]  # the oldest
        return terms

    # ------------------------------------------------------------------ steps
    def step(self, rows, z, dt: float, cov=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predict and update filters ``rows`` with point ``z`` (3,) after ``dt``.

        ``cov`` (3, 3), if given, is the point's own covariance
        (:meth:`ModelFilter.step`); such a step is not isotropic: with the scalar rows it is
        whitened by C = L Lᵀ (y and ∂f/∂q by L⁻¹, R = ρC becomes ρI, log-likelihood − log det L,
        as ``fast_update`` does for one filter, the same update up to round-off), else the filters
        step one by one.

        Returns the log-likelihoods, the NIS and whether each row failed
        (len(rows),). A filter whose innovation covariance is not positive
        definite keeps its state and gets log-likelihood ``MIN_LOG_LIKELIHOOD``
        and NIS inf, as in the selector's loop over :meth:`ModelFilter.step`.
        """
        rows = tuple(rows)
        if self.scalar:
            white = None if cov is None else self._whitening(cov)
            if cov is None or white is not None:
                return self._step_scalar(rows, np.asarray(z, dtype=float), float(dt), white)
        if not self.stacked or cov is not None:
            return self._step_each(rows, z, dt, cov)
        with np.errstate(all="ignore"):  # a failing row computes NaN/inf; it is dropped below
            result, failed = self._step_stacked(rows, np.asarray(z, dtype=float), float(dt))
        return self._keep(rows, result, failed)

    def _keep(self, rows, result, failed):
        """The rows that did not fail take their new state and pending update; returns :meth:`step`'s results."""
        fails = failed.tolist()
        broken = any(fails)
        log_lik = np.where(failed, MIN_LOG_LIKELIHOOD, result.log_likelihood) if broken else result.log_likelihood
        nis = np.where(failed, np.inf, result.nis) if broken else result.nis
        xs, Ps = [], []
        for i, j in enumerate(rows):
            if not fails[i]:
                f = self.filters[j]
                f.x, f.P = x, P = result.x[i], result.P[i]
                f.set_pending_update(result, i)
                xs.append(x)
                Ps.append(P)
        self._state = None if broken else (rows, result.x, result.P, xs, Ps)
        return log_lik, nis, failed

    def _step_each(self, rows, z, dt, cov=None):
        log_lik, nis = np.empty(len(rows)), np.empty(len(rows))
        failed = np.zeros(len(rows), dtype=bool)
        for i, j in enumerate(rows):
            try:
                update = self.filters[j].step(z, dt, cov)
            except InnovationCovarianceError:  # a numerically broken structure explains nothing
                log_lik[i], nis[i], failed[i] = MIN_LOG_LIKELIHOOD, np.inf, True
                continue
            log_lik[i], nis[i] = update.log_likelihood, update.nis
        return log_lik, nis, failed

    def rerun(self, rows, points, dts, first: int, covs=None) -> list[int]:
        """Filter rows ``rows`` through ``points[first:]`` (after a refit); returns the rows that failed.

        ``covs``, if given, holds each point's own covariance (:meth:`step`).

        A row whose innovation covariance breaks down stops there (its state
        is then the caller's to restore), as :meth:`ModelFilter.start` does.
        """
        active, failed = list(rows), []
        if self.scalar and rows:
            first = self._rerun_scalar(tuple(active), points, dts, first, covs)
        for i in range(first, len(points)):
            if not active:
                break
            *_, broken = self.step(active, points[i], float(dts[i]), None if covs is None else covs[i])
            if broken.any():
                failed += [j for j, b in zip(active, broken) if b]
                active = [j for j, b in zip(active, broken) if not b]
        return failed

    def _rerun_scalar(self, rows, points, dts, first: int, covs=None) -> int:
        """:meth:`rerun`'s steps but the last with the compiled rows, in one call (:func:`rerun_rows`, the
        operations of :func:`step_rows` step by step): only the states are kept.

        Stops before the last point (left to :meth:`step`, which records the rows' latest updates) or
        before a step where a row fails or the point's covariance is not positive definite (left to
        :meth:`step` too, which handles them). Returns the index of the first point still to be stepped.
        """
        last = len(points) - 1
        if first >= last:
            return first
        whitenings = []
        if covs is not None:
            for i in range(first, last):
                white = self._whitening(covs[i])
                if white is None:
                    break  # not positive definite: this step is step()'s
                whitenings.append(white)
            last = first + len(whitenings)
            if last == first:
                return first
        hs = [float(dts[i]) for i in range(first, last)]
        noises = {h: self._stacked_noise(rows, h) for h in dict.fromkeys(hs)}  # a tail's gaps: a few sizes
        _, rho, two_log_rho, scale, two_log_scale = noises[hs[0]]  # ρ: the same for every δt
        Qs = np.array([noises[h][0] for h in hs])
        if covs is None:
            Ls, log_det_ls, whiten = np.zeros((len(hs), 3, 3)), np.zeros(len(hs)), False  # unused
        else:
            Ls, log_det_ls, whiten = np.array([w[0] for w in whitenings]), np.array([w[1] for w in whitenings]), True
        X, P = self._stacked_state(rows)
        kinds, packed = self._row_structures(rows)
        X, P, taken = rerun_rows(X, P, Qs, np.array(hs), np.asarray(points[first:last], dtype=float),
                                 kinds, packed, scale if whiten else rho,
                                 two_log_scale if whiten else two_log_rho, Ls, whiten, log_det_ls)
        if taken > 0:
            for k, j in enumerate(rows):
                self.filters[j].x, self.filters[j].P = X[k], P[k]
            self._state = None
        return first + taken

    def _step_stacked(self, rows, z, dt):
        """:meth:`ModelFilter.step` of every row at once, with the same operations (module docstring)."""
        fs = [self.filters[j] for j in rows]
        F = step_matrices(fs[0].settings.order, 1, dt, 0.0)[0]
        Q, rho, two_log_rho, *_ = self._stacked_noise(rows, dt)
        X, P = self._stacked_state(rows)
        # ekf.predict: X⁻ = F X, P⁻ = F P Fᵀ + Q, symmetrised
        X_pred = (F @ X[:, :, None])[:, :, 0]
        P_pred = F @ P @ F.T + Q
        P_pred = 0.5 * (P_pred + P_pred.transpose(0, 2, 1))
        q_pred = (fs[0].select @ X_pred[:, :, None])[:, :, 0]
        points = [self._points[j](f.structure, q_pred[i]) for i, (j, f) in enumerate(zip(rows, fs))]
        z_pred = np.array([p[0] for p in points])
        J = np.array([p[1] for p in points])  # (r, 3): ∂f/∂q of each row
        y = z - z_pred
        # isotropic_update, d = 1: M = ρ + a|j|², S⁻¹ j = j/M
        a = P_pred[:, 0, 0]
        jj = (J[:, None, :] @ J[:, :, None])[:, 0, 0]
        jy = (J[:, None, :] @ y[:, :, None])[:, 0, 0]
        yy = (y[:, None, :] @ y[:, :, None])[:, 0, 0]
        M = rho + a * jj
        failed = ~((rho > 0.0) & (M > 0.0) & np.isfinite(M))
        nis = yy / rho - a * jy * jy / (rho * M)
        log_likelihood = np.maximum(-0.5 * (nis + two_log_rho + np.log(M) + 3 * LOG_2PI), MIN_LOG_LIKELIHOOD)
        p0 = P_pred[:, :, 0]
        x_new = X_pred + p0 * (jy / M)[:, None]  # K y, K = p0 jᵀ/M
        k = p0 * (jj / M)[:, None]  # K J
        n = X.shape[1]
        I_KH = np.broadcast_to(np.eye(n), (len(rows), n, n)).copy()
        I_KH[:, :, 0] -= k
        outer = p0[:, :, None] * p0[:, None, :]
        P_new = I_KH @ P_pred @ I_KH.transpose(0, 2, 1) + ((rho * jj / (M * M))[:, None, None]) * outer  # Joseph
        P_new = 0.5 * (P_new + P_new.transpose(0, 2, 1))
        return BankStep(x_new, P_new, y, a, J, rho, log_likelihood, nis), failed

    def _step_scalar(self, rows, z, dt, white=None):
        """:meth:`_step_stacked` for order 1, compiled (:func:`stslam.selection.scalar_rows.step_rows`).

        ``white``: (L⁻¹ (3, 3), log det L, C) of the point's own covariance (:meth:`step`), or None.
        """
        Q, rho, two_log_rho, scale, two_log_scale = self._stacked_noise(rows, dt)
        X, P = self._stacked_state(rows)
        kinds, packed = self._row_structures(rows)
        X_new, P_new, y, a, J, nis, log_lik, failed = step_rows(
            X, P, Q, dt, z, kinds, packed,
            rho if white is None else scale, two_log_rho if white is None else two_log_scale,
            _NO_WHITENING if white is None else white[0], white is not None, 0.0 if white is None else white[1])
        step = BankStep(X_new, P_new, y, a, J, rho if white is None else scale, log_lik, nis,
                        None if white is None else white[2])
        return self._keep(rows, step, failed)

    def _whitening(self, cov):
        """:func:`_whitening` of a point's covariance, kept: a rerun after a refit steps through the same
        points, with the same covariance arrays, again. The array is held with it, so its id is not reused."""
        kept = self._whitenings.get(id(cov))
        if kept is not None and kept[0] is cov:
            return kept[1]
        white = _whitening(cov)
        self._whitenings[id(cov)] = (cov, white)
        if len(self._whitenings) > WHITENINGS_KEPT:
            del self._whitenings[next(iter(self._whitenings))]  # the oldest
        return white

    def _row_structures(self, rows) -> tuple[np.ndarray, np.ndarray]:
        """The rows' kinds (r,) and packed structures (r, 12) (:func:`stslam.selection.scalar_rows.pack`),
        kept until one of the rows is fitted again."""
        key = (rows, tuple(self.filters[j].generation for j in rows))
        if self._structures is None or self._structures[0] != key:
            self._structures = (key, self._kinds[list(rows)], self._packed(rows))
        return self._structures[1:]

    def _packed(self, rows) -> np.ndarray:
        """The rows' structures packed (r, 12) (:func:`stslam.selection.scalar_rows.pack`), each kept until its next fit."""
        out = []
        for j in rows:
            f, cached = self.filters[j], self._constants.get(j)
            if cached is None or cached[0] != f.generation:
                cached = self._constants[j] = (f.generation, pack(int(self._kinds[j]), f.structure))
            out.append(cached[1])
        return np.array(out)


def _whitening(cov):
    """(L⁻¹ (3, 3), log det L, C) of a point's covariance C = L Lᵀ (3, 3); None when C is not
    positive definite (the filters then step one by one, each failing as ModelFilter.step does).

    The Cholesky factor and its inverse written out on Python floats (numpy's calls cost more
    than the arithmetic of a 3 × 3 matrix): L is that of numpy.linalg.cholesky up to round-off.
    """
    C = np.asarray(cov, dtype=float)
    (c00, _, _), (c10, c11, _), (c20, c21, c22) = C.tolist()
    d0 = c00
    if not (d0 > 0.0 and math.isfinite(d0)):
        return None
    l00 = math.sqrt(d0)
    l10, l20 = c10 / l00, c20 / l00
    d1 = c11 - l10 * l10
    if not (d1 > 0.0 and math.isfinite(d1)):
        return None
    l11 = math.sqrt(d1)
    l21 = (c21 - l20 * l10) / l11
    d2 = c22 - l20 * l20 - l21 * l21
    if not (d2 > 0.0 and math.isfinite(d2)):
        return None
    l22 = math.sqrt(d2)
    m00, m11, m22 = 1.0 / l00, 1.0 / l11, 1.0 / l22
    m10 = -l10 * m00 * m11
    m21 = -l21 * m11 * m22
    m20 = -(l20 * m00 + l21 * m10) * m22
    inverse = np.array([[m00, 0.0, 0.0], [m10, m11, 0.0], [m20, m21, m22]])
    return inverse, math.log(l00) + math.log(l11) + math.log(l22), C
