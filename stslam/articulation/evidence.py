"""What a fit window says about a fitted structure: its uncertainty and whether the data support it.

Two questions about a structure C fitted to a window of n points (SPEC 2),
answered with pure functions, points in metres, world frame:

1. **How uncertain is C where the filter predicts the next point?** The fit's
   Fisher information gives the covariance of C's parameters θ; propagated to
   the predicted point z* it is the covariance (3, 3) of the structure's
   position there, *across* the structure (along the path the motion variable q
   absorbs it). Added to σ_z² I, this makes the innovation covariance the
   predictive covariance of a structure fitted on n points (SPEC 4 likelihood):

       S = H P⁻ Hᵀ + Σ_C(z*) + σ_z² I,    Σ_C(z*) = (I − Π_J) N D* Σ_θ D*ᵀ Nᵀ (I − Π_J),

   with D* = ∂r/∂θ the Jacobian of the structure's residual r (the point's
   offset across the structure, in the orthonormal directions N) at z*,
   Σ_θ = σ_z² (Σ_i D_iᵀ D_i)⁺ over the window (Gauss–Newton Fisher inverse) and
   Π_J the projector onto the columns of ∂f/∂q. The penalty grows with the
   number of structure parameters and with how far z* lies outside the window
   (its leverage), so a 6-parameter circle that fits no better than a
   4-parameter line predicts with a wider S and loses on likelihood. Used
   with the selection setting ``structure_uncertainty: fisher``
   (:class:`stslam.selection.model_filter.FilterSettings`).

   * static (SPEC 2.1): θ = P0, Σ_θ = σ_z²/n I₃;
   * prismatic (SPEC 2.2): θ = offsets and tilts of the line across its
     direction n̂ = v₁ (towards v₂, v₃, the other principal axes). The tilt
     variances come from first-order eigenvector perturbation of the scatter
     matrix A = Σ (z_i − P0)(z_i − P0)ᵀ with eigenvalues λ₁ ≥ λ₂ ≥ λ₃:
     var(tilt_k) = σ_z²(λ₁ + λ_k)/(λ₁ − λ_k)², which tends to the regression
     value σ_z²/Σ l_i² for a long window and grows without bound when the
     window is a round blob (direction undetermined); var(offset_k) = σ_z²/n;
   * revolute (SPEC 2.3): θ = (centre c (3), tilt of the normal n̂ towards v₁,
     v₂ (2), radius r); residuals: height h = n̂ᵀ(z − c) and radial distance
     ρ = ‖w‖ − r, w = (z − c) − h n̂, u = w/‖w‖:
     ∂h/∂c = −n̂ᵀ, ∂h/∂tilt_k = v_kᵀ(z − c), ∂ρ/∂c = −uᵀ,
     ∂ρ/∂tilt_k = −h u ᵀv_k, ∂ρ/∂r = −1.

2. **Do the observations support declaring a model?** Model selection
   (SPEC 4) compares models whose predictions are nearly alike early on,
   because they are nested: a line travelled at zero speed is a static
   point, a circle of infinite radius is a line. Their one-step likelihood
   ratios are then small and noisy, and Algorithm 1's first crossing of
   τ = 0.6 can follow noise. Two classical tests say what the data support
   (σ̂² is a noise variance per coordinate, :func:`noise_variance`):

   * motion (:func:`motion_p_value`): "the point did not move" is rejected
     by the static model's goodness of fit, RSS_static/σ̂² ~ χ²_{3(n−1)}, or
     by a significant least-squares velocity, |b̂|² Σ(t − t̄)²/σ̂² ~ χ²₃
     (Bonferroni-combined);
   * curvature (:func:`circle_support`, SPEC 2.4: "collinear points for a
     circle" are not applicable): a circle adds 2 parameters to a line
     (curvature, and the plane's turn about the line), so
     F = (RSS_line − RSS_circle)/(2σ̂²) ~ F_{2, 2n−6} for points on a line,
     with σ̂² = max(σ_z², RSS_circle/(2n − 6)) from the circle's own residual
     (a σ_z that is too small then does not make noise look like curvature).

   Each test rejects a true null with probability at most its level α.
"""

from __future__ import annotations

import numpy as np
from scipy.special import chdtrc, fdtri

from stslam.articulation.circle_kernels import scatter_axes
from stslam.articulation.models import check_points_world

# Residual dimensions m (offsets across the structure) and free parameters p of
# each structure: a point (3, 3); a line (2, 4: a point on it 2, direction 2);
# a circle (2, 6: centre 3, normal 2, radius 1). A fit on n points leaves
# n·m − p degrees of freedom.
RESIDUAL_DIMENSIONS = {"static": (3, 3), "prismatic": (2, 4), "revolute": (2, 6)}

# Smallest eigenvalue gap λ₁ − λ_k used in the tilt variance, relative to λ₁:
# keeps an exactly round window finite (its tilt variance is then ~1e12 σ²/λ₁).
MIN_RELATIVE_GAP = 1e-6


# ------------------------------------------------------------------ parameter covariances

def principal_axes(points_world) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mean (3,), eigenvalues λ (3,) (descending, m²) and axes (3, 3) (rows) of the window's scatter matrix."""
    p = check_points_world(points_world)
    if p.shape[0] >= 3:  # the thin SVD, compiled (U is n x 3, not n x n: a long track would need n² memory)
        return scatter_axes(p)
    mean = p.mean(axis=0)
    d = p - mean
    _, s, vt = np.linalg.svd(d, full_matrices=True)  # below 3 rows the full one, so that vt is (3, 3)
    lam = np.zeros(3)
    lam[:s.size] = s ** 2
    return mean, lam, vt


def line_tilt_variances(eigenvalues, sigma_m: float) -> np.ndarray:
    """Variances (2,) (rad²) of the tilt of v₁ towards v₂ and v₃: σ²(λ₁ + λ_k)/(λ₁ − λ_k)² (module docstring).

    ``eigenvalues`` (3,): λ of the scatter matrix, descending (m²); ``sigma_m``: σ_z (m).
    """
    lam = np.asarray(eigenvalues, dtype=float)
    gap = np.maximum(lam[0] - lam[1:], MIN_RELATIVE_GAP * max(lam[0], np.finfo(float).tiny))
    return sigma_m ** 2 * (lam[0] + lam[1:]) / gap ** 2


def circle_residual_jacobian(points_world, centre_world, normal, v1, v2) -> np.ndarray:
    """∂(h, ρ)/∂θ for each point, shape (n, 2, 6); θ = (δc (3), tilt to v₁, tilt to v₂, δr).

    Rows: height h = n̂ᵀ(z − c), radial ρ = ‖w‖ − r (module docstring, SPEC 2.3).
    """
    p = check_points_world(points_world)
    d = p - centre_world
    h = d @ normal
    w = d - np.outer(h, normal)
    u = w / np.maximum(np.linalg.norm(w, axis=1, keepdims=True), np.finfo(float).tiny)
    D = np.zeros((p.shape[0], 2, 6))
    D[:, 0, :3] = -normal
    D[:, 0, 3] = d @ v1
    D[:, 0, 4] = d @ v2
    D[:, 1, :3] = -u
    D[:, 1, 3] = -h * (u @ v1)
    D[:, 1, 4] = -h * (u @ v2)
    D[:, 1, 5] = -1.0
    return D


def gauss_newton_covariance(D, sigma_m: float) -> np.ndarray:
    """Σ_θ = σ² (Σ_i D_iᵀ D_i)⁺ for residual Jacobians D (n, m, p); shape (p, p)."""
    D = np.asarray(D, dtype=float)
    information = np.einsum("nmi,nmj->ij", D, D)
    return sigma_m ** 2 * np.linalg.pinv(information, hermitian=True)


def _project_across(cov, jacobian_q) -> np.ndarray:
    """(I − Π_J) cov (I − Π_J) with Π_J the projector onto the columns of ∂f/∂q (3, dof)."""
    J = np.asarray(jacobian_q, dtype=float)
    if J.size == 0 or not np.any(J):
        return cov
    Pi = J @ np.linalg.pinv(J)
    M = np.eye(3) - Pi
    out = M @ cov @ M.T
    return 0.5 * (out + out.T)


# ------------------------------------------------------------------ the thin object

class StructureCovariance:
    """Covariance of a fitted structure's position at any point, from its fit window.

    Build with :meth:`for_model` once per fit; call :meth:`at` (cheap) at each
    predicted point.

    Parameters
    ----------
    kind : {"static", "prismatic", "revolute"}
    frame : numpy.ndarray, shape (3, 3) or None
        Rows are the structure's axes: prismatic (n̂, v₂, v₃); revolute (v₁, v₂, n̂).
    origin : numpy.ndarray, shape (3,)
        Static and prismatic: P0; revolute: the circle centre c (m).
    cov_theta : numpy.ndarray, shape (p, p)
        Σ_θ in the parametrisation of the module docstring.
    """

    def __init__(self, kind: str, origin, frame, cov_theta):
        self.kind = kind
        self.origin = np.asarray(origin, dtype=float)
        self.frame = None if frame is None else np.asarray(frame, dtype=float)
        self.cov_theta = np.asarray(cov_theta, dtype=float)

    @classmethod
    def for_model(cls, model_name: str, structure, fit_points_world, sigma_m: float) -> "StructureCovariance":
        """Σ_θ of ``structure`` fitted on ``fit_points_world`` (n, 3) with noise σ_z = ``sigma_m`` (m)."""
        p = check_points_world(fit_points_world)
        n = p.shape[0]
        if model_name == "static":
            return cls("static", structure.p0, None, sigma_m ** 2 / n * np.eye(3))
        if model_name == "prismatic":
            _, lam, axes = principal_axes(p)
            direction = structure.direction
            # v₂, v₃: the other principal axes, orthogonalised against the fitted n̂.
            across = axes[1:] - np.outer(axes[1:] @ direction, direction)
            across /= np.linalg.norm(across, axis=1, keepdims=True)
            cov = np.diag(np.concatenate([np.full(2, sigma_m ** 2 / n), line_tilt_variances(lam, sigma_m)]))
            return cls("prismatic", structure.p0, np.vstack([direction, across]), cov)
        if model_name == "revolute":
            centre, normal = structure.centre_world, structure.normal
            D = circle_residual_jacobian(p, centre, normal, structure.v1, structure.v2)
            frame = np.vstack([structure.v1, structure.v2, normal])
            return cls("revolute", centre, frame, gauss_newton_covariance(D, sigma_m))
        raise ValueError(f"no structure covariance for model {model_name!r}")

    def at(self, z_world, jacobian_q) -> np.ndarray:
        """Σ_C(z*) (3, 3), m², world frame: the structure's position covariance across the path at z*."""
        z = np.asarray(z_world, dtype=float)
        if self.kind == "static":
            cov = self.cov_theta
        elif self.kind == "prismatic":
            along = float((z - self.origin) @ self.frame[0])
            # displacement along v_k: offset_k + l·tilt_k
            var = self.cov_theta[[0, 1], [0, 1]] + along ** 2 * self.cov_theta[[2, 3], [2, 3]]
            across = self.frame[1:]
            cov = across.T @ np.diag(var) @ across
        else:
            v1, v2, normal = self.frame
            D = circle_residual_jacobian(z[None, :], self.origin, normal, v1, v2)[0]  # (2, 6)
            d = z - self.origin
            w = d - (d @ normal) * normal
            u = w / max(float(np.linalg.norm(w)), np.finfo(float).tiny)
            N = np.column_stack([normal, u])  # residual rows (h, ρ) → world directions
            cov = N @ D @ self.cov_theta @ D.T @ N.T
        return _project_across(0.5 * (cov + cov.T), jacobian_q)


# ------------------------------------------------------------------ support tests

def circle_support(points_world, circle_residual_m: float, sigma_m: float, alpha: float) -> str | None:
    """None when the window supports a circle's curvature at level ``alpha``; else the reason (module docstring, 2.).

    Parameters
    ----------
    points_world : array_like, shape (n, 3)
        The window the circle was fitted on (m).
    circle_residual_m : float
        RMS distance (m) of the window to the fitted circle (``residual_m``).
    sigma_m : float
        Configured noise σ_z (m), the floor of the noise estimate.
    alpha : float
        Probability of supporting a circle when the points lie on a line, in (0, 1).
    """
    p = check_points_world(points_world)
    n = p.shape[0]
    dof = 2 * n - 6
    if dof < 1:
        return f"a circle's curvature needs at least 4 points to be tested, got {n}"
    _, lam, _ = principal_axes(p)
    rss_circle = n * circle_residual_m ** 2
    rss_line = float(lam[1] + lam[2])
    var = max(sigma_m ** 2, rss_circle / dof)
    curvature = max(rss_line - rss_circle, 0.0) / (2.0 * var)
    limit = float(fdtri(2, dof, 1.0 - alpha))  # F_{2,dof} quantile (scipy.stats.f.ppf's own function)
    if curvature <= limit:
        return (f"curvature not supported by the window: F = {curvature:.2f} ≤ {limit:.2f} "
                f"(n = {n}, α = {alpha:g})")
    return None


def noise_variance(fits, sigma_m: float) -> float:
    """σ̂² (m²): the smallest per-coordinate residual variance RSS/(n·m − p) of the fits, floored at σ_z².

    ``fits`` is an iterable of (model name, RMS residual (m), n points). Each
    fit that holds the truth estimates σ² without bias; a wrong one
    overestimates it, hence the minimum. The floor keeps a lucky small
    residual from making noise look like motion.
    """
    best = np.inf
    for name, residual_m, n in fits:
        m, p = RESIDUAL_DIMENSIONS[name]
        if n * m > p:
            best = min(best, n * residual_m ** 2 / (n * m - p))
    return max(sigma_m ** 2, best if np.isfinite(best) else 0.0)


def motion_p_value(points_world, times_s, noise_var: float) -> float:
    """p-value of "the point did not move" over a track (module docstring, 2.).

    Two tests, Bonferroni-combined, p = min(1, 2·min(p_trend, p_spread)), so
    that slow steady motion (trend) and motion that comes back (spread) are
    both caught: trend, the least-squares velocity b̂ of z(t) = a + b t, with
    |b̂|² Σ(t − t̄)²/σ̂² ~ χ²₃ for a static point; spread, the static model's
    goodness of fit Σ‖z_i − z̄‖²/σ̂² ~ χ²_{3(n−1)}.

    Parameters
    ----------
    points_world : array_like, shape (n, 3)
        Observed positions (m).
    times_s : array_like, shape (n,)
        Their times (s, or frames), increasing.
    noise_var : float
        σ̂², noise variance per coordinate (m²) (:func:`noise_variance`);
        it must not come from the static fit of these points.

    Returns
    -------
    float
        The p-value in [0, 1]; 1 for fewer than 3 points.
    """
    p = check_points_world(points_world)
    t = np.asarray(times_s, dtype=float).reshape(-1)
    if t.shape[0] != p.shape[0]:
        raise ValueError(f"times_s must have shape ({p.shape[0]},), got {t.shape}")
    stats = MotionStatistics()
    for ti, zi in zip(t, p):
        stats.add(ti, zi)
    return stats.p_value(noise_var)


def weighted_motion_p_value(points_world, times_s, covs, excess_var: float = 0.0) -> float:
    """:func:`motion_p_value` for points with their own covariances C_i (3, 3) (m²).

    Generalised least squares with weights W_i = (C_i + e I)⁻¹, e = ``excess_var``
    (m², the residual variance beyond what C_i holds): spread, the static model's
    fit Σ (z_i − z̄)ᵀ W_i (z_i − z̄) ~ χ²_{3(n−1)}, z̄ = (Σ W_i)⁻¹ Σ W_i z_i; trend, the
    velocity b̂ of z = a + b t with b̂ᵀ Cov(b̂)⁻¹ b̂ ~ χ²₃, Cov(b̂)⁻¹ the Schur complement
    Σ τ²W − (Σ τW)(Σ W)⁻¹(Σ τW) of the normal equations, τ = t − t̄. With C_i = σ²I
    it is :func:`motion_p_value` with σ̂² = σ² + e. A point seen through an uncertain
    robot pose carries that pose's share in C_i (SPEC 13), so its apparent wander
    is weighed against it instead of read as motion.
    """
    p = check_points_world(points_world)
    n = p.shape[0]
    if n < 3:
        return 1.0
    t = np.asarray(times_s, dtype=float).reshape(-1)
    C = np.asarray(covs, dtype=float).reshape(n, 3, 3) + excess_var * np.eye(3)
    W = np.linalg.inv(C)
    tau = t - t.mean()
    sw, stw, sttw = W.sum(axis=0), np.einsum("n,nij->ij", tau, W), np.einsum("n,nij->ij", tau * tau, W)
    wz = np.einsum("nij,nj->ni", W, p)
    z_bar = np.linalg.solve(sw, wz.sum(axis=0))
    d = p - z_bar
    rss = float(np.einsum("ni,ni->", d, np.einsum("nij,nj->ni", W, d)))
    info_b = sttw - stw @ np.linalg.solve(sw, stw)  # Cov(b̂)⁻¹
    rhs = np.einsum("n,ni->i", tau, wz) - stw @ np.linalg.solve(sw, wz.sum(axis=0))
    trend = float(rhs @ np.linalg.lstsq(info_b, rhs, rcond=None)[0]) if np.any(tau) else 0.0  # b̂ᵀ info b̂
    p_trend = float(chdtrc(3, trend))
    p_spread = float(chdtrc(3 * (n - 1), rss))
    return min(1.0, 2.0 * min(p_trend, p_spread))


class MotionStatistics:
    """Running centred sums of a track for :func:`motion_p_value`, O(1) per point.

    Welford's updates: n, means t̄ and z̄, S_tt = Σ(t − t̄)², S_zz = Σ‖z − z̄‖²
    and S_tz = Σ(t − t̄)(z − z̄) (3,), so a long track costs no more per step
    than a short one and large coordinates lose no precision. The three axes
    are kept as Python floats; their dot products accumulate from +0 in order,
    as the BLAS kernel of a 3-vector ``@`` does, so the sums are those of the
    array form.
    """

    def __init__(self):
        self.n = 0
        self.mean_t = 0.0
        self._mean_z = [0.0, 0.0, 0.0]
        self.stt = 0.0
        self.szz = 0.0
        self._stz = [0.0, 0.0, 0.0]
        self._kept = None  # (n, σ̂², p) of the latest p_value

    @property
    def mean_z(self) -> np.ndarray:
        return np.array(self._mean_z)

    @property
    def stz(self) -> np.ndarray:
        return np.array(self._stz)

    def add(self, t: float, z_world) -> None:
        """Add the point ``z_world`` (3,) (m) observed at time ``t``."""
        z = np.asarray(z_world, dtype=float).tolist()
        self.n += 1
        dt = t - self.mean_t
        dz = [z[k] - self._mean_z[k] for k in range(3)]
        self.mean_t += dt / self.n
        mean = [self._mean_z[k] + dz[k] / self.n for k in range(3)]
        self._mean_z = mean
        self.stt += dt * (t - self.mean_t)
        rest = [z[k] - mean[k] for k in range(3)]
        self.szz += ((0.0 + dz[0] * rest[0]) + dz[1] * rest[1]) + dz[2] * rest[2]
        self._stz = [self._stz[k] + dt * rest[k] for k in range(3)]

    def p_value(self, noise_var: float) -> float:
        """:func:`motion_p_value` of the points added so far, with σ̂² = ``noise_var`` (m²); kept until the next
        point or another σ̂² (the decisions ask several times per observation)."""
        if self.n < 3:
            return 1.0
        kept = self._kept
        if kept is not None and kept[0] == self.n and kept[1] == noise_var:
            return kept[2]
        p = self._p_value(noise_var)
        self._kept = (self.n, noise_var, p)
        return p

    def _p_value(self, noise_var: float) -> float:
        stt = self.stt
        b = [v / stt for v in self._stz] if stt > 0 else [0.0, 0.0, 0.0]  # least-squares velocity
        bb = ((0.0 + b[0] * b[0]) + b[1] * b[1]) + b[2] * b[2]
        # chdtrc(k, x) = P(χ²_k > x), the survival function without scipy.stats' overhead
        p_trend = float(chdtrc(3, bb * stt / noise_var))
        p_spread = float(chdtrc(3 * (self.n - 1), self.szz / noise_var))
        return min(1.0, 2.0 * min(p_trend, p_spread))
