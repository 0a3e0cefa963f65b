"""Compiled circle and revolute-structure fits (SPEC 2.3, 2.4): the numbers of
:mod:`stslam.articulation.circle_fit` and :meth:`stslam.articulation.models.RevoluteModel.fit`.

Each structure refit of the online selector and each window's evidence fits a circle; in numpy every
step (distinct rows, centring, SVD, Taubin's eigenproblem, the geometric refinement, the angles) was a
call costing more than its arithmetic. These kernels are the same steps compiled (numba, cached); the
Python functions check their input, call them and raise :class:`~stslam.errors.DegenerateFitError` with
the reason a status code gives (:data:`OK`, :data:`FEW_POINTS`, :data:`COLLINEAR`,
:data:`INFINITE_RADIUS`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from stslam.articulation.small_lm import CIRCLE_2D, levenberg_marquardt

OK, FEW_POINTS, COLLINEAR, INFINITE_RADIUS = 0, 1, 2, 3
# Points whose second principal spread is below this fraction of the first are treated as collinear: a
# circle through them has a radius beyond ~1/tol times the extent of the points (no joint makes that).
COLLINEAR_RELATIVE_TOL = 1e-9
# MINPACK's lmder settings the geometric fit has always used: tolerances at round-off, and at most
# 100 evaluations per parameter (as ``least_squares(method="lm")`` runs it).
GEOMETRIC_TOLERANCE = 1e-14
GEOMETRIC_EVALUATIONS = 300


@njit(cache=True)
def distinct_rows_upto(p, k):
    """min(number of distinct rows of ``p`` (n, d), k): stops at the k-th distinct row."""
    found = np.empty(k, dtype=np.int64)
    count = 0
    for i in range(p.shape[0]):
        new = True
        for f in range(count):
            if np.all(p[i] == p[found[f]]):
                new = False
                break
        if new:
            found[count] = i
            count += 1
            if count == k:
                break
    return count


@njit(cache=True)
def normalise(p):
    """(status, u, m, s): points (n, 2) centred on their centroid m and scaled to unit RMS distance s;
    status COLLINEAR when the second singular value is below ``COLLINEAR_RELATIVE_TOL`` of the first."""
    n = p.shape[0]
    m = np.array([np.sum(p[:, 0]) / n, np.sum(p[:, 1]) / n])
    d = p - m
    s = np.sqrt(np.sum(d * d) / n)
    u = d / s
    sv = np.linalg.svd(u, full_matrices=False)[1]
    return (COLLINEAR if sv[1] <= COLLINEAR_RELATIVE_TOL * sv[0] else OK), u, m, s


@njit(cache=True)
def algebraic(u, m, s):
    """(status, centre (2,), radius) of Taubin's fit (:func:`stslam.articulation.circle_fit.fit_circle_algebraic`)
    of normalised points ``u``; status INFINITE_RADIUS when the quadratic term vanishes."""
    n = u.shape[0]
    x, y = u[:, 0], u[:, 1]
    z = x * x + y * y
    z_mean = np.sum(z) / n  # = 1 by the normalisation, kept for clarity
    w = np.empty((n, 3))
    w[:, 0], w[:, 1], w[:, 2] = z - z_mean, x, y
    M = w.T @ w / n
    n_sqrt_inv = 1.0 / np.sqrt(np.array([4.0 * z_mean, 1.0, 1.0]))
    _, vectors = np.linalg.eigh(M * np.outer(n_sqrt_inv, n_sqrt_inv))
    a = n_sqrt_inv * vectors[:, 0]  # a = N^{-1/2} b, smallest eigenvalue
    A, B, C = a[0], a[1], a[2]
    D = -A * z_mean
    if abs(A) <= COLLINEAR_RELATIVE_TOL * max(abs(B), abs(C), abs(A)):
        return INFINITE_RADIUS, np.zeros(2), 0.0
    centre = m + s * np.array([-B / (2.0 * A), -C / (2.0 * A)])
    return OK, centre, s * np.sqrt(max(B * B + C * C - 4.0 * A * D, 0.0)) / (2.0 * abs(A))


@njit(cache=True)
def geometric(u, m, s, centre0, radius0):
    """(centre (2,), radius) of the geometric fit of normalised points ``u`` from (centre0, radius0)
    (Levenberg–Marquardt, :mod:`stslam.articulation.small_lm`)."""
    start = np.empty(3)
    start[:2] = (centre0 - m) / s
    start[2] = radius0 / s
    theta, _, _ = levenberg_marquardt(CIRCLE_2D, start, u, np.ones(0), np.zeros((3, 3)), GEOMETRIC_TOLERANCE,
                                      GEOMETRIC_TOLERANCE, GEOMETRIC_TOLERANCE, GEOMETRIC_EVALUATIONS)
    return m + s * theta[:2], s * abs(theta[2])


@njit(cache=True)
def fit_circle(p):
    """(status, distinct rows up to 3, centre (2,), radius): algebraic fit refined geometrically."""
    distinct = distinct_rows_upto(p, 3)
    if distinct < 3:
        return FEW_POINTS, distinct, np.zeros(2), 0.0
    status, u, m, s = normalise(p)
    if status != OK:
        return status, distinct, np.zeros(2), 0.0
    status, centre0, radius0 = algebraic(u, m, s)
    if status != OK:
        return status, distinct, np.zeros(2), 0.0
    centre, radius = geometric(u, m, s, centre0, radius0)
    return OK, distinct, centre, radius


@njit(cache=True)
def unwrap(phi):
    """numpy.unwrap of angles (n,) (rad, period 2π, discontinuity π)."""
    out = phi.copy()
    correction = 0.0
    for i in range(1, phi.size):
        dd = phi[i] - phi[i - 1]
        ddmod = np.mod(dd + np.pi, 2.0 * np.pi) - np.pi
        if ddmod == -np.pi and dd > 0.0:
            ddmod = np.pi
        if abs(dd) >= np.pi:
            correction += ddmod - dd
        out[i] = phi[i] + correction
    return out


@njit(cache=True)
def increasing(values):
    """Whether ``values`` (n,) trend upwards (least-squares slope ≥ 0)."""
    n = values.size
    t = np.arange(n) - (n - 1) / 2.0
    return np.sum(t * (values - np.sum(values) / n)) >= 0.0


@njit(cache=True)
def revolute_fit(p):
    """(status, distinct, p0, v1, v2, centre_xy, radius, residual) of
    :meth:`stslam.articulation.models.RevoluteModel.fit` (its docstring) on points (n, 3)."""
    n = p.shape[0]
    zero3 = np.zeros(3)
    distinct = distinct_rows_upto(p, 3)
    if distinct < 3:
        return FEW_POINTS, distinct, zero3, zero3, zero3, np.zeros(2), 0.0, 0.0
    p0 = np.array([np.sum(p[:, 0]) / n, np.sum(p[:, 1]) / n, np.sum(p[:, 2]) / n])
    d = p - p0
    _, _, vt = np.linalg.svd(d, full_matrices=False)
    v1, v2 = vt[0].copy(), vt[1].copy()
    xy = np.empty((n, 2))
    xy[:, 0], xy[:, 1] = d @ v1, d @ v2
    status, distinct, centre, radius = fit_circle(xy)
    if status != OK:
        return status, distinct, zero3, zero3, zero3, np.zeros(2), 0.0, 0.0
    phi = unwrap(np.arctan2(xy[:, 1] - centre[1], xy[:, 0] - centre[0]))
    if not increasing(phi):
        v2 = -v2
        xy[:, 1] = -xy[:, 1]
        centre = np.array([centre[0], -centre[1]])
    normal = np.cross(v1, v2)
    total = 0.0
    for i in range(n):
        height = d[i] @ normal
        radial = np.sqrt((xy[i, 0] - centre[0]) ** 2 + (xy[i, 1] - centre[1]) ** 2) - radius
        total += height * height + radial * radial
    return OK, distinct, p0, v1, v2, centre, radius, np.sqrt(total / n)


@njit(cache=True)
def revolute_angles(p, p0, v1, v2, centre_xy):
    """:meth:`stslam.articulation.models.RevoluteModel.motion_variable`: the unwrapped in-plane angles (n,)."""
    d = p - p0
    return unwrap(np.arctan2(d @ v2 - centre_xy[1], d @ v1 - centre_xy[0]))


@njit(cache=True)
def line_fit(p):
    """(distinct rows up to 2, p0, direction, residual) of :meth:`stslam.articulation.models.PrismaticModel.fit`
    (its docstring) on points (n, 3): the mean, the first right-singular vector signed to grow over the window,
    the RMS distance to the line."""
    n = p.shape[0]
    distinct = distinct_rows_upto(p, 2)
    if distinct < 2:
        return distinct, np.zeros(3), np.zeros(3), 0.0
    p0 = np.array([np.sum(p[:, 0]) / n, np.sum(p[:, 1]) / n, np.sum(p[:, 2]) / n])
    d = p - p0
    _, _, vt = np.linalg.svd(d, full_matrices=False)
    first = np.ascontiguousarray(vt[0])
    direction = first / np.sqrt(first @ first)
    along = d @ direction
    if not increasing(along):
        direction = -direction
        along = -along
    total = 0.0
    for i in range(n):
        for c in range(3):
            e = d[i, c] - along[i] * direction[c]
            total += e * e
    return distinct, p0, direction, np.sqrt(total / n)


@njit(cache=True)
def scatter_axes(p):
    """(mean (3,), λ (3,) descending (m²), axes (3, 3) as rows) of a window (n ≥ 3, 3)'s scatter matrix: the thin
    SVD of the centred points, λ = s² (:func:`stslam.articulation.evidence.principal_axes`)."""
    n = p.shape[0]
    mean = np.array([np.sum(p[:, 0]) / n, np.sum(p[:, 1]) / n, np.sum(p[:, 2]) / n])
    _, s, vt = np.linalg.svd(p - mean, full_matrices=False)
    return mean, s * s, vt
