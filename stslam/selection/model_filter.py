"""One articulation model's Kalman filter over its motion state (SPEC 3, SPEC 4).

A model M with ``dof``-dimensional motion variable q and temporal order k keeps
the motion state

    X = [q, q⁽¹⁾, …, q⁽ᵏ⁾]   (dimension (k+1)·dof, blocks of ``dof`` per derivative),

so the per-axis Taylor model of SPEC 3 lifts to the whole state by a Kronecker
product: F = A ⊗ I_dof, Q = Q₁ ⊗ I_dof (each axis of q gets independent noise
η ~ N(0, σ_η²) on its (k+1)-th derivative; :class:`stslam.kalman.temporal.MotionModel`).
The measurement is the 3D point

    z = f_M(C, q) + ν,   ν ~ N(0, σ_z² I₃)   (world frame, m),

linearised as H = [∂f/∂q, 0, …, 0] (shape (3, (k+1)·dof)). The Kalman
equations themselves come from :mod:`stslam.kalman.ekf` only.

Units: q is in the model's own unit (static and prismatic: m, revolute: rad),
but σ_η is given in metres at the point, per s^(k+1) (or per frame^(k+1) when
δt is one frame), the same physical unit for every model: it is divided by
the point's speed per unit of q, s = ‖∂f/∂q‖_F/√dof (1 for prismatic, √3
for the static [1,1,1] perturbation, the radius r for revolute). A hand
that pushes a door or a drawer accelerates the handle by similar amounts in
m/s²; with σ_η in rad/s² instead, a circle of tiny radius fitted to noise
would be an almost free model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from stslam.kalman import ekf
from stslam.kalman.isotropic import isotropic_update
from stslam.errors import DegenerateFitError
from stslam.articulation.evidence import RESIDUAL_DIMENSIONS, StructureCovariance, noise_variance
from stslam.kalman.temporal import MotionModel
from stslam.selection.initial_state import (evenly_spaced_run, initial_motion_state,  # noqa: F401
                                          selection_matrix, step_matrices)


@dataclass(frozen=True)
class FilterSettings:
    """Settings of one model's filter.

    Attributes
    ----------
    order : int
        Temporal order k (SPEC 3; the paper uses 1, constant velocity).
    sigma_eta : float
        Process-noise standard deviation on the (k+1)-th derivative of the
        point's position along its path, m per time^(k+1) (m/s² for k = 1);
        see the module docstring for the conversion to q's unit.
    measurement_sigma_m : float
        Standard deviation σ_z of each coordinate of an observed point (m).
    smoothing_sigma : float
        Gaussian width (samples) of the derivative estimate at initialisation (SPEC 3).
    init_window : int
        Number of observations the motion state is initialised from.
    structure_uncertainty : {"inflation", "fisher"}
        How the uncertainty of the fitted structure C enters the innovation
        covariance S. ``"inflation"`` (default): R = σ_z²(1 + κ·p/n)·I with
        κ = ``structure_inflation``. ``"fisher"``: the fit's Fisher
        information propagated to the predicted point,
        S = H P⁻ Hᵀ + Σ_C(z*) + σ_z² I (:mod:`stslam.articulation.evidence`),
        which grows with the number of structure parameters and with the
        point's leverage outside the window. Measured on the paper's three
        landmarks (σ_z = 0.04 m, 100 seeds, steps 7–14): mean NIS of the true
        model 2.2–3.5 with ``"fisher"`` (χ²₃: 3, calibrated), 1.1–2.2 with
        ``"inflation"`` (S about twice too wide, which tempers the evidence).
    structure_inflation : float
        κ of ``"inflation"``: C has p free parameters (:data:`STRUCTURE_DOF`)
        and is fitted on n points; the predictive variance of a least-squares
        fit at an average point is σ²(1 + p/n), larger one step past the end
        of the window (for a line fitted to 7 evenly spaced samples, 0.71
        against an average of 2/7), hence κ = 3. It is isotropic and the same
        at every point: a static point's mean has leverage 1/n only.
    rerun_steps : int
        After a (re)fit, the motion state is initialised just before the last
        ``rerun_steps`` observations of the window and filtered through them
        (a constant-velocity filter forgets older data within a few tens of
        steps, so this bounds the cost of a refit).
    min_radius_m : float
        A fitted circle with a smaller radius (m) is no joint: the fit counts as
        degenerate (SPEC 2.4). 0 accepts every circle.
    scale_cap_m : float
        Cap on the speed scale s used to convert σ_η to q's unit:
        σ_η,q = σ_η / min(s, cap). For a revolute joint s is the radius, so
        above the cap the tangential noise grows like σ_η·r/cap: a prior that
        joints with very large radii are unlikely, without which a huge
        circle fitted to a straight path would tie with the line for ever.
        inf (default) leaves σ_η in m at the point for every radius.
    fast_update : bool
        With ``"inflation"``, update in q's dimension
        (:func:`stslam.kalman.isotropic.isotropic_update`; equal up to round-off).
    """

    order: int = 1
    sigma_eta: float = 0.01
    measurement_sigma_m: float = 0.04
    smoothing_sigma: float = 0.6
    init_window: int = 7
    structure_inflation: float = 3.0
    structure_uncertainty: str = "inflation"
    rerun_steps: int = 30
    min_radius_m: float = 0.0
    scale_cap_m: float = float("inf")
    fast_update: bool = False


# Free parameters of each structure C: a 3D point; a line (2 for a point on it,
# 2 for its direction); a circle in 3D (centre 3, normal 2, radius 1).
STRUCTURE_DOF = {name: p for name, (_, p) in RESIDUAL_DIMENSIONS.items()}

# ---------------------------------------------------------------------- the filter

# Temporal models kept per filter, by their σ_η,q (static and prismatic refits, and
# revolute ones beyond the scale cap, come back to the same few values).
MOTION_MODELS_KEPT = 8


class ModelFilter:
    """Structure C plus a Kalman filter over the motion state of one model.

    Parameters
    ----------
    model : articulation model
        An object of :mod:`stslam.articulation.models` (``name``, ``dof``, ``fit``,
        ``position``, ``jacobian``, ``motion_variable``).
    settings : FilterSettings

    Attributes
    ----------
    structure : structure or None
        The fitted structure C (None before :meth:`start`).
    x, P : numpy.ndarray
        Motion state ((k+1)·dof,) and its covariance.
    structure_covariance : StructureCovariance or None
        Σ_C of the fit (``structure_uncertainty = "fisher"`` only).
    last_update : stslam.kalman.ekf.Update or None
        The latest update (innovation, S, NIS, log-likelihood).
    motion, R, select
        The current fit's temporal model (F, Q per δt), measurement covariance
        (3, 3) without Σ_C, and [I_dof, 0, …] (q out of the motion state).
    generation : int
        Counts the (re)fits, so that a cache of the current fit's matrices knows when it is stale.
    """

    def __init__(self, model, settings: FilterSettings):
        self.model = model
        self.settings = settings
        self.structure = None
        self.x = None
        self.P = None
        self.R = settings.measurement_sigma_m ** 2 * np.eye(3)
        self.structure_covariance = None
        self._last_update = None  # an Update, or (stslam.selection.bank.BankStep, row) until it is read
        self.generation = 0
        self._previous = None
        self._motions: dict[float, MotionModel] = {}
        self.structure_dof = getattr(model, "structure_dof", STRUCTURE_DOF.get(model.name, 0))
        self.n_fit, self.fit_points = 0, None
        self.select = selection_matrix(settings.order, model.dof)
        self.motion = MotionModel(settings.order, model.dof, settings.sigma_eta)  # F, Q per δt (SPEC 3)

    @property
    def name(self) -> str:
        return self.model.name

    @property
    def last_update(self) -> ekf.Update | None:
        if isinstance(self._last_update, tuple):
            step, row = self._last_update
            self._last_update = step.update(row)
        return self._last_update

    @last_update.setter
    def last_update(self, update: ekf.Update | None) -> None:
        self._last_update = update

    def set_pending_update(self, step, row: int) -> None:
        """The latest update is row ``row`` of a bank step (:mod:`stslam.selection.bank`), built when read."""
        self._last_update = (step, row)

    def snapshot(self) -> tuple:
        """The motion state and latest update, for :meth:`restore`."""
        return self.x, self.P, self._last_update

    def restore(self, snapshot: tuple) -> None:
        """Go back to a :meth:`snapshot` (same structure)."""
        self.x, self.P, self._last_update = snapshot

    def start(self, points_world, dts, fit_points_world=None, covs=None) -> None:
        """Fit C on the window and filter the window with it (SPEC 2, SPEC 3).

        The structure is fitted on ``fit_points_world`` (m, 3) (default: every
        point of ``points_world`` (n, 3)); the motion state is initialised
        (SPEC 3) from the ``init_window`` points that precede the last
        ``rerun_steps`` ones (their latest evenly spaced run,
        :func:`evenly_spaced_run`) and then filtered through the rest, so a
        refit on a grown window (SPEC 6.3(b)) keeps what the filter learnt.
        ``dts`` (n,) holds the time from each observation to the next-earlier
        one (``dts[0]`` unused). Raises :class:`~stslam.errors.DegenerateFitError`
        when the window is degenerate for this model (SPEC 2.4); the filter is
        then unchanged. ``covs`` (n, 3, 3), if given, are the observations' own
        covariances (:meth:`step`).
        """
        first = self.prepare(points_world, dts, fit_points_world)
        try:
            for i in range(first, len(points_world)):
                self.step(np.asarray(points_world[i], dtype=float), float(dts[i]),
                          None if covs is None else covs[i])
        except ekf.InnovationCovarianceError as error:
            self.restore_previous()
            raise DegenerateFitError(f"filtering the window failed: {error}") from error

    def prepare(self, points_world, dts, fit_points_world=None, structure=None) -> int:
        """The fit and initialisation of :meth:`start`, without filtering the rest of the window.

        Returns the index of the first observation still to be filtered (by
        :meth:`step`, or a bank's rerun, :mod:`stslam.selection.bank`); only the
        last ``rerun_steps + init_window`` entries of ``points_world`` and
        ``dts`` (sequences) are read. ``structure``, if given, is this model's fit of
        ``fit_points_world`` made already (the same structure, not fitted again).
        :meth:`restore_previous` undoes it.
        """
        n = len(points_world)
        tail = max(0, n - self.settings.rerun_steps - self.settings.init_window)
        points = np.asarray(points_world[tail:], dtype=float)
        dts = np.asarray(dts[tail:], dtype=float)
        fit_points = points if fit_points_world is None else np.asarray(fit_points_world, dtype=float)
        if fit_points_world is None and tail > 0:
            fit_points = np.asarray(points_world, dtype=float)
        structure = self.model.fit(fit_points) if structure is None else structure  # SPEC 2 fit
        radius = getattr(structure, "radius", None)
        if radius is not None and radius < self.settings.min_radius_m:
            raise DegenerateFitError(f"fitted radius {radius:.4f} m is below the minimum "
                                     f"{self.settings.min_radius_m} m of a joint")
        n_tail = points.shape[0]
        m = min(self.settings.init_window, n_tail)
        first, m = evenly_spaced_run(dts, max(0, n_tail - self.settings.rerun_steps - m), m)
        q = self.model.motion_variable(structure, points[first:first + m])  # initialise on points[first:first + m]
        # σ_q: point noise per coordinate (σ_z, or the fit's residual variance per
        # coordinate and degree of freedom if larger: a structure that fits badly
        # predicts loosely) through the pseudo-inverse of ∂f/∂q at the last sample.
        J = self.model.jacobian(structure, q[-1])
        sigma_point = math.sqrt(noise_variance([(self.name, structure.residual_m, fit_points.shape[0])],
                                               self.settings.measurement_sigma_m))
        JtJ = J.T @ J
        a = float(JtJ[0, 0])  # one axis: pinv([[a]]) is 1/a, the same number (0 < a < inf)
        q_var = sigma_point ** 2 * (np.array([1.0 / a]) if JtJ.shape == (1, 1) and 0.0 < a < np.inf
                                    else np.diag(np.linalg.pinv(JtJ)))
        dt0 = small_mean(dts[first + 1:first + m]) if m > 1 else 1.0
        self._previous = (self.structure, self.x, self.P, self.R, self.motion, self.structure_covariance)
        # s = ‖∂f/∂q‖_F/√dof (m per unit q); one axis: √(JᵀJ), the same dot product as np.linalg.norm's
        speed = math.sqrt(a) if JtJ.shape == (1, 1) else float(np.linalg.norm(J)) / np.sqrt(self.model.dof)
        sigma_eta_q = self.settings.sigma_eta / max(min(speed, self.settings.scale_cap_m), 1e-12)
        self.motion = self._motion_model(sigma_eta_q)
        x, P = initial_motion_state(q, self.settings.order, dt0, self.settings.smoothing_sigma,
                                    np.sqrt(q_var))
        _, Q = step_matrices(self.settings.order, self.model.dof, dt0, sigma_eta_q)
        self.structure, self.x, self.P = structure, x, P + Q  # Q keeps P positive definite
        self.n_fit, self.fit_points = fit_points.shape[0], fit_points  # the points C was fitted on
        self.generation += 1
        sigma_z = self.settings.measurement_sigma_m
        if self.settings.structure_uncertainty == "fisher":
            self.R = sigma_z ** 2 * np.eye(3)
            self.structure_covariance = StructureCovariance.for_model(self.name, structure, fit_points, sigma_z)
        else:
            inflation = 1.0 + self.settings.structure_inflation * self.structure_dof / self.n_fit
            self.R = inflation * sigma_z ** 2 * np.eye(3)  # R = σ²(1 + κp/n) I
            self.structure_covariance = None
        return tail + first + m

    def _motion_model(self, sigma_eta_q: float) -> MotionModel:
        """The temporal model with noise σ_η,q, kept for the next fits (its F, Q stay cached per δt)."""
        motion = self._motions.pop(sigma_eta_q, None)
        if motion is None:
            motion = MotionModel(self.settings.order, self.model.dof, sigma_eta_q)
        self._motions[sigma_eta_q] = motion
        while len(self._motions) > MOTION_MODELS_KEPT:
            del self._motions[next(iter(self._motions))]  # the least recently used
        return motion

    def restore_previous(self) -> None:
        """Undo the latest :meth:`prepare` (structure, motion state, R and Σ_C; not n_fit or the latest update)."""
        (self.structure, self.x, self.P, self.R, self.motion,
         self.structure_covariance) = self._previous
        self.generation += 1

    def step(self, z_world, dt: float, cov=None) -> ekf.Update:
        """Predict one step of ``dt`` and update with the point ``z_world`` (3,) (SPEC 4).

        ``cov`` (3, 3), m², if given, is this observation's own covariance in
        place of σ_z² I (e.g. the sensor noise plus the robot pose's share,
        SPEC 13): with ``"inflation"``, R = cov·(1 + κp/n); with ``"fisher"``,
        R = cov + Σ_C(z*). Returns the :class:`stslam.kalman.ekf.Update`, whose
        ``log_likelihood`` is log N(y; 0, S) of the innovation y = z − f(C, q⁻).
        """
        F, Q = self.motion.matrices(dt)
        x_pred, P_pred = ekf.predict(self.x, self.P, F, Q)  # X⁻ = F X, P⁻ = F P Fᵀ + Q
        q_pred = self.select @ x_pred
        z_pred = self.model.position(self.structure, q_pred)
        y = np.asarray(z_world, dtype=float) - z_pred
        J = self.model.jacobian(self.structure, q_pred)
        H = J @ self.select  # H = [∂f/∂q, 0, …]
        R = self.R if cov is None else self.R[0, 0] / self.settings.measurement_sigma_m ** 2 * cov
        if self.structure_covariance is not None:  # S = H P⁻ Hᵀ + Σ_C(z*) + σ_z² I
            R = R + self.structure_covariance.at(z_pred, J)
            result = ekf.update(x_pred, P_pred, y, H, R)
        elif self.settings.fast_update and cov is None:  # R = ρI: the same update in q's dimension
            result = isotropic_update(x_pred, P_pred, y, J, float(R[0, 0]))
        elif self.settings.fast_update:  # R = L Lᵀ: whitened by L⁻¹, R becomes I
            result = _whitened_update(x_pred, P_pred, y, J, R)
        else:
            result = ekf.update(x_pred, P_pred, y, H, R)
        self.x, self.P = result.x, result.P
        self.last_update = result
        return result

    def predicted_positions(self, n_ahead: int, dt: float) -> np.ndarray:
        """Mean positions f(C, q) of the next ``n_ahead`` steps (no noise), shape (n_ahead, 3)."""
        F, _ = self.motion.matrices(dt)
        x = self.x.copy()
        q = np.empty((n_ahead, self.model.dof))
        for i in range(n_ahead):
            x = F @ x
            q[i] = self.select @ x
        return self.model.position(self.structure, q)


def small_mean(values: np.ndarray) -> float:
    """np.mean of a 1-D float array, the same number: below 8 elements numpy adds them in order from 0.0
    (its pairwise sum's base case), as Python's sum does, without numpy's call overhead."""
    if values.shape[0] >= 8:
        return float(np.mean(values))
    items = values.tolist()
    return sum(items) / len(items)


def _whitened_update(x, P, y, J, R) -> ekf.Update:
    """:func:`stslam.kalman.ekf.update` with H = [J, 0, …] via the isotropic update of L⁻¹y, L⁻¹J, R = L Lᵀ.

    The same posterior (the Joseph form is invariant to the whitening: K_w K_wᵀ = K R Kᵀ);
    log N(y; 0, S) = log N(L⁻¹y; 0, L⁻¹ S L⁻ᵀ) − log det L. Update keeps the unwhitened y and S.
    """
    try:
        L = np.linalg.cholesky(R)
    except np.linalg.LinAlgError as error:
        raise ekf.InnovationCovarianceError(f"the observation covariance is not positive definite: {R!r}") from error
    L_inv = np.linalg.inv(L)
    white = isotropic_update(x, P, L_inv @ y, L_inv @ J, 1.0)
    log_likelihood = max(white.log_likelihood - float(np.log(np.diag(L)).sum()), ekf.MIN_LOG_LIKELIHOOD)
    S = J @ P[:J.shape[1], :J.shape[1]] @ J.T + R
    return ekf.Update(white.x, white.P, y, S, log_likelihood, white.nis)
