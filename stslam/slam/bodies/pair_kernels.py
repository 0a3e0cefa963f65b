"""Compiled statistics of two landmarks' tracks at their common frames (SPEC 13 grouping, SPEC 18 links).

Every revision tests each pair of moving landmarks whose windows changed: their common kept frames,
whether they moved at the same times (:func:`co_moving_kernel`) and whether their distance stayed
constant (:func:`rigidity_kernel`). The numbers are those of the formulas in
:func:`stslam.slam.bodies.decisions.co_moving` and :func:`stslam.slam.bodies.joint.rigidity_test`
(which call these kernels); compiled with numba (cached on disk) because the pairs are many and
each is a few small array operations.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def common_frames(frames_a, frames_b):
    """Indices (ia, ib) of the frames two sorted, duplicate-free frame arrays share, in order."""
    ia = np.empty(min(frames_a.size, frames_b.size), dtype=np.int64)
    ib = np.empty_like(ia)
    i = j = n = 0
    while i < frames_a.size and j < frames_b.size:
        if frames_a[i] == frames_b[j]:
            ia[n], ib[n] = i, j
            n += 1
            i += 1
            j += 1
        elif frames_a[i] < frames_b[j]:
            i += 1
        else:
            j += 1
    return ia[:n], ib[:n]


@njit(cache=True)
def _block_means(points, block):
    """Means of consecutive blocks of ``block`` rows of ``points`` (n, 3); a last partial block is left out."""
    n = points.shape[0] // block
    means = np.zeros((n, 3))
    for k in range(n):
        for i in range(k * block, (k + 1) * block):
            for c in range(3):
                means[k, c] += points[i, c]
        for c in range(3):
            means[k, c] /= block
    return means


@njit(cache=True)
def co_moving_kernel(points_a, points_b, block, threshold):
    """:func:`stslam.slam.bodies.decisions.co_moving`: the Pearson correlation of the two tracks' block
    means' distances from their first block exceeds ``threshold`` (at least 4 blocks; False when either
    distance sequence is constant)."""
    n = points_a.shape[0] // block
    if n < 4:
        return False
    a, b = _block_means(points_a, block), _block_means(points_b, block)
    da, db = np.empty(n), np.empty(n)
    for k in range(n):
        da[k] = np.sqrt(np.sum((a[k] - a[0]) ** 2))
        db[k] = np.sqrt(np.sum((b[k] - b[0]) ** 2))
    ca, cb = da - da.mean(), db - db.mean()
    sa, sb = np.sqrt(np.mean(ca * ca)), np.sqrt(np.mean(cb * cb))
    if sa == 0.0 or sb == 0.0:
        return False
    return np.mean(ca * cb) / (sa * sb) > threshold


@njit(cache=True)
def block_spread(points, block):
    """Largest distance (m) between the means of two blocks of ``block`` consecutive points (0 for fewer than 2)."""
    means = _block_means(points, block)
    best = 0.0
    for i in range(means.shape[0]):
        for j in range(i + 1, means.shape[0]):
            best = max(best, np.sqrt(np.sum((means[i] - means[j]) ** 2)))
    return best


@njit(cache=True)
def rigidity_kernel(points_a, points_b, covs_a, covs_b, block):
    """(statistic, dof, spread) of :func:`stslam.slam.bodies.joint.rigidity_test` (its docstring):
    d_t = |p_a − p_b|, var_t = u_tᵀ(Σ_a + Σ_b)u_t, statistic Σ w_t (d_t − d̄)² with w = 1/var and d̄
    the w-weighted mean, dof n − 1, spread the smaller of the two tracks' block spreads."""
    n = points_a.shape[0]
    d = np.empty(n)
    w = np.empty(n)
    for t in range(n):
        diff = points_a[t] - points_b[t]
        d[t] = np.sqrt(diff @ diff)
        u = diff / max(d[t], 1e-12)
        var = u @ (covs_a[t] + covs_b[t]) @ u
        w[t] = 1.0 / max(var, 1e-18)
    d_mean = np.sum(w * d) / np.sum(w) if n else 0.0
    statistic = np.sum(w * (d - d_mean) ** 2)
    spread = min(block_spread(points_a, block), block_spread(points_b, block))
    return statistic, max(n - 1, 0), spread


@njit(cache=True)
def pair_link(frames_a, points_a, covs_a, frames_b, points_b, covs_b, min_common, co_block, correlation,
              spread_block):
    """The link test of two windows up to its p-value: (candidate, statistic, dof, spread).

    ``candidate`` is False when the common frames are fewer than ``min_common`` or the tracks did not
    move at the same times (:func:`co_moving_kernel`); the rest is :func:`rigidity_kernel` at the common
    frames (zeros when not a candidate).
    """
    ia, ib = common_frames(frames_a, frames_b)
    if ia.size < min_common:
        return False, 0.0, 0, 0.0
    pa, pb = points_a[ia], points_b[ib]
    if not co_moving_kernel(pa, pb, co_block, correlation):
        return False, 0.0, 0, 0.0
    statistic, dof, spread = rigidity_kernel(pa, pb, covs_a[ia], covs_b[ib], spread_block)
    return True, statistic, dof, spread
