"""Compiled loops of a window's evidence (SPEC 13, 18), run once per landmark or linked pair whose window
changed at every revision: :func:`stslam.articulation.window_evidence.rest_means`' walk over a window
(the same IEEE operations in the same order as the Python loop it replaced, so the same numbers:
numba does not reorder floating-point arithmetic without ``fastmath``) and the χ² of a pair's
difference about its weighted mean (:func:`turn_statistic`, 3 × 3 inverses by cofactors where numpy
used LAPACK: equal to round-off) and its score along the pair's motion (:func:`turn_score`).
Compiled (cached on disk) because numpy's per-call overheads on
3-vectors and 3 × 3 matrices were most of the time.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True)
def rest_runs(points, variances, limit):
    """Runs of observations at rest (:func:`~stslam.articulation.window_evidence.rest_means`): each run's
    mean (m, 3) and its summed weight Σ 1/v (m,). An observation (n, 3) with variance v (n,) joins the
    current run while its squared distance from the run's mean is at most ``limit`` · v."""
    n = points.shape[0]
    means = np.empty((n, 3))
    weights = np.empty(n)
    m = 0
    tx = ty = tz = weight = 0.0
    for i in range(n):
        x, y, z, v = points[i, 0], points[i, 1], points[i, 2], variances[i]
        if weight > 0.0:
            mx, my, mz = tx / weight, ty / weight, tz / weight
            dx, dy, dz = x - mx, y - my, z - mz
            if dx * dx + dy * dy + dz * dz > limit * v:
                means[m, 0], means[m, 1], means[m, 2] = mx, my, mz
                weights[m] = weight
                m += 1
                tx = ty = tz = weight = 0.0
        tx, ty, tz, weight = tx + x / v, ty + y / v, tz + z / v, weight + 1.0 / v
    means[m, 0], means[m, 1], means[m, 2] = tx / weight, ty / weight, tz / weight
    weights[m] = weight
    return means[:m + 1].copy(), weights[:m + 1].copy()


@njit(cache=True)
def inverse3(a, out) -> bool:
    """``out`` (9,) ← the inverse of the 3 × 3 matrix ``a`` (9,) (row-major) by cofactors; False (out
    untouched) when it is singular (det 0 or not finite)."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8 = a[0], a[1], a[2], a[3], a[4], a[5], a[6], a[7], a[8]
    c0, c3, c6 = a4 * a8 - a5 * a7, a5 * a6 - a3 * a8, a3 * a7 - a4 * a6
    det = a0 * c0 + a1 * c3 + a2 * c6
    if det == 0.0 or not math.isfinite(det):
        return False
    r = 1.0 / det
    out[0], out[1], out[2] = c0 * r, (a2 * a7 - a1 * a8) * r, (a1 * a5 - a2 * a4) * r
    out[3], out[4], out[5] = c3 * r, (a0 * a8 - a2 * a6) * r, (a2 * a3 - a0 * a5) * r
    out[6], out[7], out[8] = c6 * r, (a1 * a6 - a0 * a7) * r, (a0 * a4 - a1 * a3) * r
    return True


@njit(cache=True)
def turn_statistic(a, b, covs_a, covs_b):
    """(ok, χ², weighted mean (3,)) of the differences d_t = a_t − b_t (n, 3) with information
    W_t = (Σ_a,t + Σ_b,t)⁻¹: d̄ = (Σ W_t)⁻¹ Σ W_t d_t, χ² = Σ (d_t − d̄)ᵀ W_t (d_t − d̄) (SPEC 13, 18;
    :func:`~stslam.articulation.window_evidence.turn_evidence`). ok False when a covariance sum or Σ W_t is
    singular."""
    n = a.shape[0]
    info = np.empty((n, 9))
    total, weighted = np.zeros(9), np.zeros(3)
    c = np.empty(9)
    for t in range(n):
        for k in range(9):
            c[k] = covs_a[t, k // 3, k % 3] + covs_b[t, k // 3, k % 3]
        if not inverse3(c, info[t]):
            return False, math.nan, np.zeros(3)
        d0, d1, d2 = a[t, 0] - b[t, 0], a[t, 1] - b[t, 1], a[t, 2] - b[t, 2]
        for i in range(3):
            weighted[i] += info[t, 3 * i] * d0 + info[t, 3 * i + 1] * d1 + info[t, 3 * i + 2] * d2
        for k in range(9):
            total[k] += info[t, k]
    inverse = np.empty(9)
    if not inverse3(total, inverse):
        return False, math.nan, np.zeros(3)
    mean = np.empty(3)
    for i in range(3):
        mean[i] = (inverse[3 * i] * weighted[0] + inverse[3 * i + 1] * weighted[1]
                   + inverse[3 * i + 2] * weighted[2])
    statistic = 0.0
    for t in range(n):
        r0, r1, r2 = a[t, 0] - b[t, 0] - mean[0], a[t, 1] - b[t, 1] - mean[1], a[t, 2] - b[t, 2] - mean[2]
        for i, ri in enumerate((r0, r1, r2)):
            statistic += ri * (info[t, 3 * i] * r0 + info[t, 3 * i + 1] * r1 + info[t, 3 * i + 2] * r2)
    return True, statistic, mean


@njit(cache=True)
def turn_score(a, b, covs_a, covs_b, mean, reference_frames):
    """Score statistic (≥ 0; 0 when undefined) of a turn of the pair difference d_t = a_t − b_t along the
    pair's displacement (SPEC 13, 18; :func:`~stslam.articulation.window_evidence.turn_evidence`).

    s_t = |m_t − m̄₀|, m_t = (a_t + b_t)/2 the pair's midpoint and m̄₀ its mean over the first
    ``reference_frames``: how far the part has moved. A turn changes d by an amount that grows with
    the part's motion, d_t ≈ c + s_t β; a slide leaves d_t = c. With W_t = (Σ_a,t + Σ_b,t)⁻¹ and d̄ the
    weighted ``mean`` (c under a slide), the score U = Σ s_t W_t (d_t − d̄) has the covariance
    V = Σ s_t² W_t − (Σ s_t W_t)(Σ W_t)⁻¹(Σ s_t W_t) under a slide, and UᵀV⁻¹U ~ χ²₃ (the midpoint's noise
    is uncorrelated with the difference's when Σ_a = Σ_b, so s may be taken as given).
    """
    n = a.shape[0]
    ref = np.zeros(3)
    count = min(reference_frames, n)
    for t in range(count):
        for i in range(3):
            ref[i] += 0.5 * (a[t, i] + b[t, i]) / count
    u, sw, ssw, total = np.zeros(3), np.zeros(9), np.zeros(9), np.zeros(9)
    c, info = np.empty(9), np.empty(9)
    for t in range(n):
        s = 0.0
        for i in range(3):
            s += (0.5 * (a[t, i] + b[t, i]) - ref[i]) ** 2
        s = math.sqrt(s)
        for k in range(9):
            c[k] = covs_a[t, k // 3, k % 3] + covs_b[t, k // 3, k % 3]
        if not inverse3(c, info):
            return 0.0
        r0, r1, r2 = a[t, 0] - b[t, 0] - mean[0], a[t, 1] - b[t, 1] - mean[1], a[t, 2] - b[t, 2] - mean[2]
        for i in range(3):
            u[i] += s * (info[3 * i] * r0 + info[3 * i + 1] * r1 + info[3 * i + 2] * r2)
        for k in range(9):
            total[k] += info[k]
            sw[k] += s * info[k]
            ssw[k] += s * s * info[k]
    inverse = np.empty(9)
    if not inverse3(total, inverse):
        return 0.0
    v = np.empty(9)  # V = ssw − sw · total⁻¹ · sw
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for k in range(3):
                for m in range(3):
                    acc += sw[3 * i + k] * inverse[3 * k + m] * sw[3 * m + j]
            v[3 * i + j] = ssw[3 * i + j] - acc
    v_inverse = np.empty(9)
    if not inverse3(v, v_inverse):
        return 0.0
    score = 0.0
    for i in range(3):
        for j in range(3):
            score += u[i] * v_inverse[3 * i + j] * u[j]
    return max(score, 0.0)


@njit(cache=True)
def swept_angle(params, points, basis) -> float:
    """Angle (rad) the points (n, 3) span about a fitted circle's centre params[:3], the largest gap left
    out; the circle's plane has the normal n0 + params[3]·e1 + params[4]·e2 (normalised), ``basis`` =
    [e1, e2, n0] (3, 3) (:func:`~stslam.articulation.window_evidence._circle_chi2`'s refinement)."""
    e1, e2, n0 = basis[0], basis[1], basis[2]
    raw = n0 + params[3] * e1 + params[4] * e2
    normal = raw / math.sqrt(raw[0] * raw[0] + raw[1] * raw[1] + raw[2] * raw[2])
    along = e1[0] * normal[0] + e1[1] * normal[1] + e1[2] * normal[2]
    u = e1 - along * normal
    u = u / math.sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2])
    v = np.array([normal[1] * u[2] - normal[2] * u[1], normal[2] * u[0] - normal[0] * u[2],
                  normal[0] * u[1] - normal[1] * u[0]])
    n = points.shape[0]
    angles = np.empty(n)
    for i in range(n):
        d0, d1, d2 = points[i, 0] - params[0], points[i, 1] - params[1], points[i, 2] - params[2]
        angles[i] = math.atan2(d0 * v[0] + d1 * v[1] + d2 * v[2], d0 * u[0] + d1 * u[1] + d2 * u[2])
    angles.sort()
    widest = angles[0] + 2.0 * math.pi - angles[n - 1]  # the gap across ±π
    for i in range(1, n):
        widest = max(widest, angles[i] - angles[i - 1])
    return 2.0 * math.pi - widest
