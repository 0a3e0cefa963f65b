"""Compiled 3 × 3 algebra of the running motion test (SPEC 13; docs/selection.md §6):
:class:`stslam.selection.observation_covariance.WeightedMotionSums`.

Every selector fed a covariance with its points adds each point's weighted sums and reads the
motion test's statistics from them once per new point. The formulas are the class docstring's;
each product and sum is written in the order the Python-float version it replaces evaluated
it (numba does not reorder floating-point arithmetic without ``fastmath``), so the numbers are
the same. The sums are one flat float array (35,): Σ W (9), Σ tW (9), Σ t²W (9) row-major,
Σ Wz (3), Σ tWz (3), Σ zᵀWz, Σ t.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from stslam.articulation.window_kernels import inverse3

N_SUMS = 35
# A 3 × 3 matrix whose |det| is below this fraction of its largest entry cubed is solved by least squares.
MIN_RELATIVE_DET = 1e-12


@njit(cache=True)
def _mat_vec(a, v):
    return np.array([a[0] * v[0] + a[1] * v[1] + a[2] * v[2], a[3] * v[0] + a[4] * v[1] + a[5] * v[2],
                     a[6] * v[0] + a[7] * v[1] + a[8] * v[2]])


@njit(cache=True)
def _mat_mat(a, b):
    out = np.empty(9)
    for i in range(3):
        for j in range(3):
            out[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j]
    return out


@njit(cache=True)
def _dot(u, v) -> float:
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


@njit(cache=True)
def _well_conditioned(a) -> bool:
    det = a[0] * (a[4] * a[8] - a[5] * a[7]) + a[1] * (a[5] * a[6] - a[3] * a[8]) + a[2] * (a[3] * a[7] - a[4] * a[6])
    scale = 0.0
    for x in a:
        scale = max(scale, abs(x))
    return math.isfinite(det) and abs(det) > MIN_RELATIVE_DET * scale ** 3.0


@njit(cache=True)
def add_point(sums, t, z0, z1, z2, cov, excess_var) -> bool:
    """Add one point z = (z0, z1, z2) (relative to the track's first) at time t with covariance ``cov``
    (3, 3) + e I to ``sums`` (35,) in place; False (sums untouched) when that covariance is singular."""
    c = np.empty(9)
    for i in range(3):
        for j in range(3):
            c[3 * i + j] = cov[i, j]
    c[0] += excess_var
    c[4] += excess_var
    c[8] += excess_var
    w = np.empty(9)
    if not inverse3(c, w):
        return False
    z = np.array([z0, z1, z2])
    wz = _mat_vec(w, z)
    tt = t * t
    for k in range(9):
        sums[k] += w[k]
        sums[9 + k] += t * w[k]
        sums[18 + k] += tt * w[k]
    for k in range(3):
        sums[27 + k] += wz[k]
        sums[30 + k] += t * wz[k]
    sums[33] += _dot(z, wz)
    sums[34] += t
    return True


@njit(cache=True)
def motion_statistics(s, n, info_b, rhs):
    """(status, trend, rss) of the sums ``s`` (35,) of ``n`` points; ``info_b`` (9,) and ``rhs`` (3,) are
    filled with Cov(b̂)⁻¹ and r. status 0: trend = rᵀ Cov(b̂) r; 1: no spread in time, trend 0;
    2: Cov(b̂)⁻¹ nearly singular, the trend is left to a least-squares solve (trend NaN);
    −1: Σ W is singular (trend and rss NaN)."""
    mean_t = s[34] / n
    tw, ttw = np.empty(9), np.empty(9)
    for k in range(9):
        a, b, c = s[k], s[9 + k], s[18 + k]
        tw[k] = b - mean_t * a
        ttw[k] = c - 2.0 * mean_t * b + mean_t * mean_t * a
    twz = np.empty(3)
    for k in range(3):
        twz[k] = s[30 + k] - mean_t * s[27 + k]
    inv_sw = np.empty(9)
    if not inverse3(s[0:9], inv_sw):
        return -1, math.nan, math.nan
    swz = s[27:30]
    z_bar = _mat_vec(inv_sw, swz)
    rss = s[33] - _dot(swz, z_bar)
    product = _mat_mat(tw, _mat_mat(inv_sw, tw))
    for k in range(9):
        info_b[k] = ttw[k] - product[k]
    tz = _mat_vec(tw, z_bar)
    for k in range(3):
        rhs[k] = twz[k] - tz[k]
    moving = False
    for k in range(9):
        if ttw[k] != 0.0:
            moving = True
    if not moving:
        return 1, 0.0, rss
    if not _well_conditioned(info_b):
        return 2, math.nan, rss
    inv_info = np.empty(9)
    if not inverse3(info_b, inv_info):
        return -1, math.nan, math.nan
    return 0, _dot(rhs, _mat_vec(inv_info, rhs)), rss
