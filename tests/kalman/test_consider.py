"""Consider parameters (the Schmidt–Kalman filter) in ekf.update_sparse and SlamState (structure_state: consider)."""

from __future__ import annotations

import numpy as np

from stslam.kalman import ekf


def _random_problem(rng, n=7, m=3):
    A = rng.normal(size=(n, n))
    P = A @ A.T + n * np.eye(n)
    x = rng.normal(size=n)
    cols = np.array([0, 2, 4, 5])
    H_cols = rng.normal(size=(m, cols.size))
    R = np.diag(rng.uniform(0.5, 2.0, m))
    y = rng.normal(size=m)
    return x, P, y, cols, H_cols, R


def test_frozen_entries_keep_their_mean_and_covariance_and_the_rest_is_the_joseph_form_with_that_gain():
    rng = np.random.default_rng(0)
    x, P, y, cols, H_cols, R = _random_problem(rng)
    frozen = np.array([4, 5])  # two of the observed columns, as a structure's δ is
    out = ekf.update_sparse(x, P, y, cols, H_cols, R, frozen=frozen)
    # reference: the dense Joseph form with the optimal gain's frozen rows set to zero
    H = np.zeros((3, x.size))
    H[:, cols] = H_cols
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    K[frozen] = 0.0
    A = np.eye(x.size) - K @ H
    np.testing.assert_allclose(out.x, x + K @ y, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(out.P, A @ P @ A.T + K @ R @ K.T, rtol=1e-10, atol=1e-12)  # round-off only
    np.testing.assert_array_equal(out.x[frozen], x[frozen])
    np.testing.assert_allclose(out.P[np.ix_(frozen, frozen)], P[np.ix_(frozen, frozen)], rtol=1e-12, atol=1e-12)
    # the frozen entries still enter S: the innovation is judged with their uncertainty
    np.testing.assert_allclose(out.S, S, rtol=1e-12)
    # and the other states' gain is the optimal one, so their covariance shrinks less than when all are updated
    full = ekf.update_sparse(x, P, y, cols, H_cols, R)
    free = np.setdiff1d(np.arange(x.size), frozen)
    assert np.trace(out.P[np.ix_(free, free)]) >= np.trace(full.P[np.ix_(free, free)]) - 1e-12


def test_a_bias_held_as_a_consider_parameter_keeps_the_estimate_consistent():
    """z = a + c + v with a constant bias c ~ N(0, σ_c²): ignoring c makes the estimate of a overconfident
    (its variance → r/n while the error keeps c's σ_c²); considering c keeps NEES at its mean 1."""
    rng = np.random.default_rng(1)
    sigma_a, sigma_c, r, n_obs, trials = 1.0, 0.3, 0.2 ** 2, 30, 2000
    nees_consider, nees_ignore = [], []
    for _ in range(trials):
        a, c = rng.normal(0.0, sigma_a), rng.normal(0.0, sigma_c)
        x, P = np.zeros(2), np.diag([sigma_a ** 2, sigma_c ** 2])
        x1, P1 = np.zeros(1), np.array([[sigma_a ** 2]])
        for _ in range(n_obs):
            z = a + c + rng.normal(0.0, np.sqrt(r))
            out = ekf.update_sparse(x, P, [z - x[0] - x[1]], [0, 1], [[1.0, 1.0]], [[r]], frozen=np.array([1]))
            x, P = out.x, out.P
            out1 = ekf.update_sparse(x1, P1, [z - x1[0]], [0], [[1.0]], [[r]])
            x1, P1 = out1.x, out1.P
        nees_consider.append((a - x[0]) ** 2 / P[0, 0])
        nees_ignore.append((a - x1[0]) ** 2 / P1[0, 0])
    # χ²(1) has mean 1 and variance 2: over 2000 trials the mean's std is 0.032, so ±0.13 is 4 σ
    assert abs(np.mean(nees_consider) - 1.0) < 0.13
    assert np.mean(nees_ignore) > 5.0  # σ_c² / (r/n) ≈ 68 times too confident


def test_slam_state_leaves_a_consider_blocks_correction_alone():
    from stslam.articulation.models import PrismaticStructure, get_model
    from stslam.slam.blocks import ArticulatedBlock, CorrectedArticulatedBlock
    from stslam.slam.core import SlamState

    structure = PrismaticStructure(np.array([2.0, 0.0, 0.5]), np.array([0.0, 1.0, 0.0]), 0.0)
    plain = ArticulatedBlock(get_model("prismatic"), structure, 1, 0.01, 0.01)
    state = SlamState(np.zeros(3), 1e-4 * np.eye(3))
    state.add_landmark(7, plain, np.array([2.0, 0.3, 0.5]), 1e-3 * np.eye(3))
    k = plain.size
    block = CorrectedArticulatedBlock(plain.model, structure, plain.order, plain.sigma_eta, plain.sigma_rate0,
                                      consider=True)
    size = block.size
    x_b = np.concatenate([state.block_mean(7), np.zeros(size - k)])
    state.replace_block(7, block, x_b, np.eye(size, k), np.diag([0.0] * k + [1e-3] * (size - k)))
    idx = state.indices(7)
    np.testing.assert_array_equal(state.frozen(), idx[k:])
    before_x, before_P = state.x[idx[k:]].copy(), state.P[np.ix_(idx[k:], idx[k:])].copy()
    state.update_landmark(7, np.array([2.05, 0.35, 0.48]), 1e-3 * np.eye(3))
    np.testing.assert_array_equal(state.x[idx[k:]], before_x)
    np.testing.assert_allclose(state.P[np.ix_(idx[k:], idx[k:])], before_P, rtol=1e-12, atol=1e-15)
    assert np.any(state.P[np.ix_(idx[:k], idx[k:])] != 0.0)  # the cross-covariance is carried and updated
