"""The compiled pair statistics (stslam.slam.bodies.pair_kernels) against the formulas as first written in numpy."""

import numpy as np
import pytest
from scipy.stats import chi2

from stslam.slam.bodies.decisions import CO_MOTION_BLOCK, CO_MOTION_CORRELATION, co_moving
from stslam.slam.bodies.joint import SPREAD_BLOCK, rigidity_test
from stslam.slam.bodies.pair_kernels import common_frames, pair_link


def _co_moving_reference(a, b):
    n = len(a) // CO_MOTION_BLOCK
    if n < 4:
        return False
    a = a[:n * CO_MOTION_BLOCK].reshape(n, CO_MOTION_BLOCK, 3).mean(axis=1)
    b = b[:n * CO_MOTION_BLOCK].reshape(n, CO_MOTION_BLOCK, 3).mean(axis=1)
    da, db = np.linalg.norm(a - a[0], axis=1), np.linalg.norm(b - b[0], axis=1)
    if np.std(da) == 0.0 or np.std(db) == 0.0:
        return False
    return float(np.corrcoef(da, db)[0, 1]) > CO_MOTION_CORRELATION


def _spread_reference(points):
    n = points.shape[0] // SPREAD_BLOCK
    if n < 2:
        return 0.0
    means = points[:n * SPREAD_BLOCK].reshape(n, SPREAD_BLOCK, 3).mean(axis=1)
    return float(np.max(np.linalg.norm(means[:, None] - means[None, :], axis=-1)))


def _rigidity_reference(a, b, ca, cb):
    diff = a - b
    d = np.linalg.norm(diff, axis=1)
    u = diff / np.maximum(d, 1e-12)[:, None]
    w = 1.0 / np.maximum(np.einsum("ni,nij,nj->n", u, ca + cb, u), 1e-18)
    d_mean = float(np.sum(w * d) / np.sum(w)) if d.size else 0.0
    stat = float(np.sum(w * (d - d_mean) ** 2))
    return stat, max(d.size - 1, 0), min(_spread_reference(a), _spread_reference(b))


def _tracks(rng, n):
    """Two points of one door (rigid, moving together), or of two parts moving at other times."""
    phi = np.concatenate([np.zeros(n // 3), np.linspace(0.0, 1.2, n - 2 * (n // 3)), np.full(n // 3, 1.2)])
    a = np.column_stack([0.5 * np.cos(phi), 0.5 * np.sin(phi), np.full(n, 1.0)])
    if rng.random() < 0.5:
        b = np.column_stack([0.3 * np.cos(phi), 0.3 * np.sin(phi), np.full(n, 0.4)])
    else:
        b = np.column_stack([np.linspace(0.0, 0.4, n)[::-1], np.zeros(n), np.full(n, 0.2)])
    sigma = rng.uniform(0.005, 0.05)
    return a + rng.normal(0.0, sigma, a.shape), b + rng.normal(0.0, sigma, b.shape), sigma


def test_pair_statistics_equal_the_numpy_formulas():
    rng = np.random.default_rng(11)
    agree = {True: 0, False: 0}
    for _ in range(200):
        n = int(rng.integers(3, 60))
        a, b, sigma = _tracks(rng, n)
        cov = np.broadcast_to(sigma ** 2 * np.eye(3), (n, 3, 3)) * rng.uniform(0.5, 2.0, (n, 1, 1))
        assert co_moving(a, b) == _co_moving_reference(a, b)
        test = rigidity_test(a, b, cov, cov)
        stat, dof, spread = _rigidity_reference(a, b, cov, cov)
        np.testing.assert_allclose([test.statistic, test.spread_m], [stat, spread], rtol=1e-10, atol=1e-15)
        assert test.dof == dof
        assert test.p_value == pytest.approx(chi2.sf(stat, dof) if dof else 1.0, rel=1e-9, abs=1e-300)
        # the fused link test on windows at interleaved frames: the same as the parts on the common frames
        frames_a = np.sort(rng.choice(2 * n, n, replace=False))
        frames_b = np.sort(rng.choice(2 * n, n, replace=False))
        ia, ib = common_frames(frames_a, frames_b)
        np.testing.assert_array_equal(frames_a[ia], frames_b[ib])
        assert set(frames_a[ia]) == set(frames_a) & set(frames_b)
        candidate, stat_l, dof_l, spread_l = pair_link(frames_a, a, cov, frames_b, b, cov, 10, CO_MOTION_BLOCK,
                                                       CO_MOTION_CORRELATION, SPREAD_BLOCK)
        pa, pb = a[ia], b[ib]
        expected = len(ia) >= 10 and _co_moving_reference(pa, pb)
        assert bool(candidate) == expected
        agree[expected] += 1
        if expected:
            np.testing.assert_allclose([stat_l, spread_l], _rigidity_reference(pa, pb, cov[ia], cov[ib])[::2],
                                       rtol=1e-10, atol=1e-15)
            assert dof_l == len(ia) - 1
    assert agree[True] > 10 and agree[False] > 10  # both outcomes were tried
