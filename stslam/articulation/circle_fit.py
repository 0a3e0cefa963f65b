"""Circle fits to planar points (SPEC 2.3, SPEC 8.1 "separate").

Pure 2D functions: points in, ``(centre (2,), radius)`` out, all in the
units of the input (metres in stslam). Two stages, as SPEC 2.3 asks:

1. :func:`fit_circle_algebraic` — Taubin's algebraic fit, a closed-form
   eigenvector solution that is nearly unbiased for short arcs (far better
   than the Kåsa fit, which shrinks the radius on short arcs).
2. :func:`fit_circle_geometric` — geometric least squares: minimise the sum of
   squared orthogonal distances Σ (‖p_i − c‖ − r)², started from stage 1.
   This is the maximum-likelihood fit under isotropic Gaussian noise on the
   points when the sample angles are unknown nuisance parameters.

Degenerate inputs (fewer than 3 distinct points, collinear points) raise
:class:`~stslam.errors.DegenerateFitError` with the reason (SPEC 2.4).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import least_squares

from stslam.articulation import circle_kernels as kernels
from stslam.articulation.circle_kernels import COLLINEAR_RELATIVE_TOL  # noqa: F401 (the threshold's home)
from stslam.errors import DegenerateFitError


def check_points_xy(points_xy) -> np.ndarray:
    """Float64 copy of planar points, shape (n, 2); ValueError for a wrong shape or NaN."""
    p = np.asarray(points_xy, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"points_xy must have shape (n, 2), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points_xy contains non-finite values")
    return p


def raise_degenerate(status: int, distinct: int) -> None:
    """DegenerateFitError for a kernel's status (:mod:`stslam.articulation.circle_kernels`); nothing for OK."""
    if status == kernels.FEW_POINTS:
        raise DegenerateFitError(f"circle fit needs at least 3 distinct points, got {distinct}")
    if status == kernels.COLLINEAR:
        raise DegenerateFitError("circle fit: the points are collinear")
    if status == kernels.INFINITE_RADIUS:
        raise DegenerateFitError("circle fit: the points are collinear (infinite radius)")


def _normalise(p: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """Centre on the centroid and scale to unit RMS distance; raise if degenerate.

    Returns the normalised points u = (p − m) / s, the centroid m (2,) and s.
    """
    distinct = int(kernels.distinct_rows_upto(p, 3))
    raise_degenerate(kernels.OK if distinct >= 3 else kernels.FEW_POINTS, distinct)
    status, u, m, s = kernels.normalise(p)
    raise_degenerate(status, distinct)
    return u, m, float(s)


def fit_circle_algebraic(points_xy) -> tuple[np.ndarray, float]:
    """Taubin's algebraic circle fit.

    The circle is the zero set of A(x² + y²) + Bx + Cy + D. In centred,
    unit-RMS coordinates (x̄ = ȳ = 0, mean z = 1 with z = x² + y²) the optimal D
    is −A·z̄, which leaves the 3-vector a = (A, B, C) and the problem

        minimise aᵀ M a  subject to  aᵀ N a = 1,

    with M the covariance of w_i = (z_i − z̄, x_i, y_i) and N = diag(4 z̄, 1, 1)
    (Taubin's constraint: the mean squared gradient of the implicit function
    over the data is 1). The solution is the generalised eigenvector of
    (M, N) with the smallest eigenvalue; as N is diagonal and positive this is
    an ordinary symmetric eigenproblem for N^{-1/2} M N^{-1/2}.

    Parameters
    ----------
    points_xy : array_like, shape (n, 2)
        Points in a plane (m), n ≥ 3 distinct and not collinear.

    Returns
    -------
    centre : numpy.ndarray, shape (2,)
        Circle centre (m), same frame as the input.
    radius : float
        Circle radius (m).

    Raises
    ------
    DegenerateFitError
        Fewer than 3 distinct points, or collinear points.
    """
    p = check_points_xy(points_xy)
    return _algebraic(*_normalise(p))


def _algebraic(u: np.ndarray, m: np.ndarray, s: float) -> tuple[np.ndarray, float]:
    """:func:`fit_circle_algebraic` of points already normalised by :func:`_normalise`."""
    status, centre, radius = kernels.algebraic(u, m, s)
    raise_degenerate(status, 3)
    return centre, float(radius)


def circle_residuals(points_xy, centre, radius) -> np.ndarray:
    """Signed orthogonal distances ‖p_i − c‖ − r (m), shape (n,)."""
    p = check_points_xy(points_xy)
    return np.linalg.norm(p - np.asarray(centre, dtype=float), axis=1) - float(radius)


def fit_circle_geometric(points_xy, centre0=None, radius0=None) -> tuple[np.ndarray, float]:
    """Geometric (orthogonal-distance) least-squares circle fit.

    Minimises Σ_i (‖p_i − c‖ − r)² over (c, r) with
    Levenberg–Marquardt (:mod:`stslam.articulation.small_lm`) and the analytic Jacobian
    ∂(‖p_i − c‖ − r)/∂c = −(p_i − c)ᵀ/‖p_i − c‖, ∂/∂r = −1 (SPEC 2.3).

    Parameters
    ----------
    points_xy : array_like, shape (n, 2)
        Points in a plane (m), n ≥ 3 distinct and not collinear.
    centre0, radius0 : array_like (2,), float, optional
        Starting circle; by default the algebraic fit :func:`fit_circle_algebraic`.

    Returns
    -------
    centre : numpy.ndarray, shape (2,)
        Circle centre (m).
    radius : float
        Circle radius (m), positive.

    Raises
    ------
    DegenerateFitError
        As :func:`fit_circle_algebraic`: fewer than 3 distinct points, or collinear ones.
    """
    p = check_points_xy(points_xy)
    u, m, s = _normalise(p)
    if centre0 is None or radius0 is None:
        centre0, radius0 = fit_circle_algebraic(p)
    return _geometric(u, m, s, centre0, radius0)


def _geometric(u: np.ndarray, m: np.ndarray, s: float, centre0, radius0) -> tuple[np.ndarray, float]:
    """:func:`fit_circle_geometric` of points normalised by :func:`_normalise`, from the circle (centre0, radius0)."""
    centre, radius = kernels.geometric(u, m, float(s), np.asarray(centre0, dtype=float), float(radius0))
    return centre, float(radius)


def fit_circle(points_xy) -> tuple[np.ndarray, float]:
    """Algebraic fit refined by geometric least squares (SPEC 2.3): centre (2,), radius (m)."""
    status, distinct, centre, radius = kernels.fit_circle(check_points_xy(points_xy))
    raise_degenerate(status, distinct)
    return centre, float(radius)


def fit_circle_constant_rate(points_xy, times_s, centre0=None, radius0=None):
    """Joint fit of a point turning at constant rate (SPEC 8.1 "joint").

    Nonlinear least squares of z_t = c + r·[cos(θ0 + ω t), sin(θ0 + ω t)] over
    (c, r, θ0, ω), with the analytic Jacobian; ∂z/∂c = I, ∂z/∂r = u_t,
    ∂z/∂θ0 = r·τ_t, ∂z/∂ω = r·t·τ_t, where u_t = [cos, sin] and τ_t = [−sin, cos]
    at angle θ0 + ω t.

    The start is the circle ``centre0``, ``radius0`` (by default
    :func:`fit_circle_algebraic` of the same points) with θ0, ω from a straight
    line fitted to the unwrapped angles of the points about that centre.

    Parameters
    ----------
    points_xy : array_like, shape (n, 2)
        Observed positions (m), n ≥ 3.
    times_s : array_like, shape (n,)
        Observation times (s; any unit, ω is per that unit).

    Returns
    -------
    centre : numpy.ndarray, shape (2,)
        Centre (m).
    radius : float
        Radius (m), positive.
    theta0 : float
        Angle at t = 0 (rad).
    omega : float
        Turning rate (rad per unit of ``times_s``).

    Raises
    ------
    DegenerateFitError
        When the starting circle cannot be fitted (fewer than 3 distinct or
        collinear points).
    """
    p = check_points_xy(points_xy)
    t = np.asarray(times_s, dtype=float).reshape(-1)
    if t.shape[0] != p.shape[0] or not np.all(np.isfinite(t)):
        raise ValueError(f"times_s must be {p.shape[0]} finite values, got shape {t.shape}")
    if p.shape[0] < 3:
        raise DegenerateFitError(f"constant-rate circle fit needs at least 3 points, got {p.shape[0]}")
    if centre0 is None or radius0 is None:
        centre0, radius0 = fit_circle_algebraic(p)
    centre0 = np.asarray(centre0, dtype=float)
    phi = np.unwrap(np.arctan2(p[:, 1] - centre0[1], p[:, 0] - centre0[0]))
    omega0, theta00 = np.polyfit(t, phi, 1)
    start = np.array([centre0[0], centre0[1], float(radius0), theta00, omega0])

    def residual(x):
        a = x[3] + x[4] * t
        model = np.column_stack([x[0] + x[2] * np.cos(a), x[1] + x[2] * np.sin(a)])
        return (model - p).reshape(-1)

    def jacobian(x):
        a = x[3] + x[4] * t
        c, s = np.cos(a), np.sin(a)
        J = np.zeros((2 * t.size, 5))
        J[0::2, 0] = 1.0
        J[1::2, 1] = 1.0
        J[0::2, 2], J[1::2, 2] = c, s
        J[0::2, 3], J[1::2, 3] = -x[2] * s, x[2] * c
        J[0::2, 4], J[1::2, 4] = -x[2] * s * t, x[2] * c * t
        return J

    x = least_squares(residual, start, jac=jacobian, method="lm", xtol=1e-12, ftol=1e-12, gtol=1e-12).x
    radius, theta0 = float(x[2]), float(x[3])
    if radius < 0.0:  # (−r, θ0) and (r, θ0 + π) are the same circle motion
        radius, theta0 = -radius, theta0 + np.pi
    return x[:2].copy(), radius, theta0, float(x[4])
