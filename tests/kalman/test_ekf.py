"""The EKF core (stslam.kalman.ekf): Joseph-form update, prediction, augmentation, NIS, degenerate S."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from stslam.kalman import ekf


def _random_spd(rng, n, scale=1.0):
    A = rng.normal(size=(n, n))
    return scale * (A @ A.T + n * np.eye(n))


def _problem(rng, n=5, m=3):
    x = rng.normal(size=n)
    P = _random_spd(rng, n)
    H = rng.normal(size=(m, n))
    R = _random_spd(rng, m, 0.1)
    y = rng.normal(size=m)
    return x, P, H, R, y


def test_joseph_update_equals_the_textbook_update_for_the_optimal_gain():
    rng = np.random.default_rng(0)
    x, P, H, R, y = _problem(rng)
    result = ekf.update(x, P, y, H, R)
    # Textbook: S = HPH' + R, K = PH'S^-1, x+ = x + Ky, P+ = (I - KH)P.
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    np.testing.assert_allclose(result.S, S, rtol=1e-13)
    np.testing.assert_allclose(result.x, x + K @ y, rtol=1e-12, atol=1e-12)
    # Entries of P are O(10); both routes are round-off apart.
    np.testing.assert_allclose(result.P, (np.eye(x.size) - K @ H) @ P, rtol=1e-11, atol=1e-11)
    assert result.nis == pytest.approx(float(y @ np.linalg.solve(S, y)), rel=1e-12)
    assert result.log_likelihood == pytest.approx(multivariate_normal(np.zeros(3), S).logpdf(y), rel=1e-12)
    assert result.accepted


def test_joseph_update_keeps_P_symmetric_positive_semidefinite_on_nearly_exact_measurements():
    # Very uncertain states (P up to 1e10) measured almost exactly (R down to 1e-12): the
    # posterior is nearly singular, and round-off decides the sign of its small eigenvalues.
    rng = np.random.default_rng(1)
    worst_textbook, worst_joseph = 0.0, 0.0
    for _ in range(2000):
        A = rng.normal(size=(3, 3))
        P = A @ A.T * 10 ** rng.uniform(0, 10) + np.diag(10 ** rng.uniform(-4, 0, 3))
        H = rng.normal(size=(2, 3))
        R = 10 ** rng.uniform(-12, -6) * np.eye(2)
        K = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        textbook = (np.eye(3) - K @ H) @ P
        textbook = 0.5 * (textbook + textbook.T)
        joseph = ekf.update(np.zeros(3), P, np.zeros(2), H, R).P
        np.testing.assert_array_equal(joseph, joseph.T)
        worst_textbook = min(worst_textbook, np.linalg.eigvalsh(textbook)[0] / np.max(np.abs(textbook)))
        worst_joseph = min(worst_joseph, np.linalg.eigvalsh(joseph)[0] / np.max(np.abs(joseph)))
    # Relative to the largest entry, eigvalsh itself errs by ~1e-16; the Joseph form stays
    # within that, while the textbook form turns clearly indefinite on some of these problems.
    assert worst_joseph >= -1e-13
    assert worst_textbook < -1e-10


def test_sparse_update_agrees_with_the_dense_update():
    rng = np.random.default_rng(2)
    x, P, _, R, y = _problem(rng, n=7)
    cols = np.array([0, 2, 5])
    H_cols = rng.normal(size=(3, 3))
    H = np.zeros((3, 7))
    H[:, cols] = H_cols
    dense, sparse = ekf.update(x, P, y, H, R), ekf.update_sparse(x, P, y, cols, H_cols, R)
    np.testing.assert_allclose(sparse.x, dense.x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sparse.P, dense.P, rtol=1e-11, atol=1e-11)
    assert sparse.nis == pytest.approx(dense.nis, rel=1e-12)


def test_prediction_is_FPF_plus_Q_symmetrised_and_takes_a_nonlinear_mean():
    rng = np.random.default_rng(3)
    x, P = rng.normal(size=4), _random_spd(rng, 4)
    F, Q = rng.normal(size=(4, 4)), _random_spd(rng, 4, 0.01)
    x_pred, P_pred = ekf.predict(x, P, F, Q)
    np.testing.assert_allclose(x_pred, F @ x, rtol=1e-14)
    np.testing.assert_allclose(P_pred, F @ P @ F.T + Q, rtol=1e-13)
    np.testing.assert_array_equal(P_pred, P_pred.T)
    fx = np.array([1.0, -2.0, 0.5, 3.0])
    np.testing.assert_array_equal(ekf.predict(x, P, F, Q, fx=fx)[0], fx)


def test_augmentation_borders_the_covariance():
    rng = np.random.default_rng(4)
    x, P = rng.normal(size=3), _random_spd(rng, 3)
    x_new, P_new = rng.normal(size=2), _random_spd(rng, 2)
    cross = rng.normal(size=(3, 2))
    x_out, P_out = ekf.augment(x, P, x_new, P_new, cross)
    np.testing.assert_array_equal(x_out, np.concatenate([x, x_new]))
    np.testing.assert_array_equal(P_out, np.block([[P, cross], [cross.T, P_new]]))
    _, P_independent = ekf.augment(x, P, x_new, P_new)
    np.testing.assert_array_equal(P_independent, np.block([[P, np.zeros((3, 2))], [np.zeros((2, 3)), P_new]]))


def test_log_likelihood_is_floored_so_model_probabilities_never_vanish():
    stats = ekf.innovation_stats(np.array([1e3]), np.array([[1e-10]]))  # log N ≈ −5e15
    assert stats[1] == ekf.MIN_LOG_LIKELIHOOD


@pytest.mark.parametrize("P, R", [
    (np.zeros((2, 2)), np.zeros((1, 1))),                        # singular: S = 0
    (np.diag([1.0, 1.0]), -2.0 * np.ones((1, 1))),               # indefinite: S = −1
    (np.array([[np.nan, 0.0], [0.0, 1.0]]), np.ones((1, 1))),    # non-finite
    (np.diag([np.inf, 1.0]), np.ones((1, 1))),                   # non-finite
], ids=["singular", "indefinite", "nan", "inf"])
def test_degenerate_innovation_covariance_is_an_error(P, R):
    H = np.array([[1.0, 0.0]])
    y = np.array([0.3])
    with pytest.raises(ekf.InnovationCovarianceError, match="innovation covariance is not positive definite"):
        ekf.update(np.zeros(2), P, y, H, R)
    with pytest.raises(ekf.InnovationCovarianceError, match="innovation covariance is not positive definite"):
        ekf.update_sparse(np.zeros(2), P, y, [0], [[1.0]], R)
    with pytest.raises(ekf.InnovationCovarianceError, match="innovation covariance is not positive definite"):
        ekf.nis_sparse(P, y.reshape(1, 1), [np.array([0])], [np.array([[1.0]])], R)


def test_batched_nis_equals_one_measurement_at_a_time():
    rng = np.random.default_rng(5)
    n = 12
    P = _random_spd(rng, n)
    sizes = [4, 6, 4, 5, 6, 4]  # measurements with different numbers of columns, interleaved
    cols = [rng.choice(n, size=c, replace=False) for c in sizes]
    H_cols = [rng.normal(size=(3, c)) for c in sizes]
    y = rng.normal(size=(len(sizes), 3))
    Rs = np.stack([_random_spd(rng, 3, 0.1) for _ in sizes])
    for R in (Rs[0], Rs):
        batched = ekf.nis_sparse(P, y, cols, H_cols, R)
        for j in range(len(sizes)):
            S, _ = ekf.innovation_covariance_sparse(P, cols[j], H_cols[j], R if R.ndim == 2 else R[j])
            assert batched[j] == pytest.approx(ekf.innovation_stats(y[j], S)[0], rel=1e-10)
    assert ekf.nis_sparse(P, np.empty((0, 3)), [], [], Rs[0]).shape == (0,)


def test_direct_lapack_cholesky_equals_scipy_cho_factor_and_cho_solve():
    # The fast route calls the LAPACK routines scipy's wrappers call: the same numbers, not just close.
    from scipy.linalg import cho_factor, cho_solve
    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 6, 9):
        S = _random_spd(rng, n)
        ours, theirs = ekf.cholesky_factor(S), cho_factor(S, lower=True)
        np.testing.assert_array_equal(np.tril(ours[0]), np.tril(theirs[0]))
        for b in (rng.normal(size=n), rng.normal(size=(n, 4)), rng.normal(size=(4, n)).T):
            np.testing.assert_array_equal(ekf.cholesky_solve(ours, b), cho_solve(theirs, b))


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_direct_lapack_cholesky_rejects_what_scipy_rejects(bad):
    S = np.eye(3)
    S[1, 2] = S[2, 1] = bad
    with pytest.raises(ValueError):
        ekf.cholesky_factor(S)
    with pytest.raises(np.linalg.LinAlgError):
        ekf.cholesky_factor(-np.eye(3))
    b = np.ones(3)
    b[0] = bad
    with pytest.raises(ValueError):
        ekf.cholesky_solve(ekf.cholesky_factor(np.eye(3)), b)
    with pytest.raises(ekf.InnovationCovarianceError):
        ekf.innovation_stats(np.zeros(3), S)


@pytest.mark.parametrize("n", [1, 5, 127, 128, 129, 300])
def test_tiled_symmetrisation_equals_the_whole_matrix_one(n):
    rng = np.random.default_rng(n)
    A = rng.normal(size=(n, n))
    whole = A.copy()
    whole += whole.T
    whole *= 0.5
    np.testing.assert_array_equal(ekf.symmetrise(A.copy(), tile=16, whole_below=0), whole)  # by tiles
    np.testing.assert_array_equal(ekf.symmetrise(A.copy(), whole_below=0), whole)
    np.testing.assert_array_equal(ekf.symmetrise(A.copy()), whole)  # in one pass below 2,048 rows
    kept = A.copy()
    np.testing.assert_array_equal(ekf.symmetrised(A), whole)  # a new array below 2,048 rows
    np.testing.assert_array_equal(A, kept)
    np.testing.assert_array_equal(ekf.symmetrised(A.copy(), whole_below=0), whole)  # by tiles, in place


@pytest.mark.parametrize(("start", "end"), [(0, 3), (3, 7), (7, 10), (4, 4)])
def test_marginalise_range_drops_exactly_those_rows_and_columns(start, end):
    rng = np.random.default_rng(3)
    A = rng.standard_normal((10, 10))
    P, x = A @ A.T, rng.standard_normal(10)
    keep = np.r_[0:start, end:10]
    x_out, P_out = ekf.marginalise_range(x, P, start, end)
    assert np.array_equal(x_out, x[keep]) and np.array_equal(P_out, P[np.ix_(keep, keep)])
    assert P_out.flags.c_contiguous and not np.shares_memory(P_out, P)


def test_marginalise_range_rejects_a_range_outside_the_state():
    with pytest.raises(ValueError, match="marginalise_range"):
        ekf.marginalise_range(np.zeros(4), np.eye(4), 2, 5)


@pytest.mark.parametrize("b", [1, 2, 5, 13])
def test_grouped_block_columns_are_the_stacked_product_to_the_last_bit(b):
    # predict_blocks multiplies the columns of b blocks sharing F as one product: the same numbers as
    # n stacked ones, so A-SLAM's tracks do not change with how its blocks are grouped.
    rng = np.random.default_rng(b)
    k = 7
    P = rng.normal(size=(120, 120))
    index = rng.choice(120, size=b * k, replace=False).reshape(b, k)
    F = rng.normal(size=(k, k))
    np.testing.assert_array_equal(ekf._times_transpose(P[:, index], F), P[:, index] @ F.T)
    np.testing.assert_array_equal(ekf._times_transpose(P[:, index[0]], F), P[:, index[0]] @ F.T)


@pytest.mark.parametrize("b", [2, 3, 40])
def test_consecutive_blocks_are_predicted_in_place_with_the_same_bits(b):
    # predict_blocks works on views of P when a group's indices are consecutive (the robot, Dyn. SLAM's blocks)
    # and on gathered copies otherwise; the same group listed in another order takes the second path.
    rng = np.random.default_rng(b)
    k, n = 6, 3 + 6 * b + 4
    A = rng.normal(size=(n, n))
    P, x = A @ A.T, rng.normal(size=n)
    F, Q, G = rng.normal(size=(k, k)), np.eye(k) * 0.01, rng.normal(size=(3, 3))
    index = 3 + np.arange(b * k).reshape(b, k)
    in_place = ekf.predict_blocks(x, P, [(np.arange(3), G, np.eye(3), None), (index, F, Q, None)])
    gathered = ekf.predict_blocks(x, P, [(np.arange(3), G, np.eye(3), None), (index[::-1], F, Q, None)])
    dense = ekf.predict(x, P, *_dense_transition(n, [(np.arange(3), G, np.eye(3)), *((i, F, Q) for i in index)]))
    assert ekf.block_span(index) == slice(3, 3 + b * k) and ekf.block_span(index[::-1]) is None
    for got, expected in zip(in_place, gathered, strict=True):
        np.testing.assert_array_equal(got, expected)
    np.testing.assert_allclose(in_place[1], dense[1], rtol=1e-12, atol=1e-9)  # F P Fᵀ + Q to round-off


def _dense_transition(n, blocks):
    F, Q = np.eye(n), np.zeros((n, n))
    for index, F_i, Q_i in blocks:
        F[np.ix_(index, index)], Q[np.ix_(index, index)] = F_i, Q_i
    return F, Q
