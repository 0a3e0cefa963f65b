"""Temporal models (SPEC 3) and the order-k Kalman filter of a directly observed q (SPEC 8.2).

filterpy's KalmanFilter is the reference implementation of the trace filter.
"""

from __future__ import annotations

from math import factorial

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from hypothesis import given, settings, strategies as st
from scipy.linalg import expm
from scipy.ndimage import gaussian_filter1d

from stslam.errors import ConfigError, DegenerateFitError
from stslam.kalman.trace_filter import filter_trace, observation_matrix
from stslam.kalman.temporal import (MotionModel, derivative_operator, initial_covariance, initial_state,
                                    noise_matrix, process_noise, transition_matrices)

orders = st.integers(min_value=0, max_value=6)
steps = st.floats(min_value=0.01, max_value=3.0)


def _shift(order: int) -> np.ndarray:
    """Continuous-time chain of integrators: d/dt [q, q', …] = N [q, q', …]."""
    return np.eye(order + 1, k=1)


@settings(max_examples=60, deadline=None)
@given(order=orders, dt=steps)
def test_transition_is_the_matrix_exponential_of_the_integrator_chain(order, dt):
    A, B = transition_matrices(order, dt)
    # A = expm(N δt) exactly; expm is accurate to ~1e-15 relative on these
    # nilpotent matrices, entries are at most 3⁶/1 ≈ 729, so 1e-12 absolute.
    np.testing.assert_allclose(A, expm(_shift(order) * dt), rtol=1e-12, atol=1e-12)
    # B holds the Taylor coefficients of a unit (k+1)-th derivative held over δt:
    # the last column of the order-(k+1) transition, without its final 1.
    A_next, _ = transition_matrices(order + 1, dt)
    np.testing.assert_allclose(B, A_next[:-1, -1], rtol=1e-15)


def test_transition_of_order_one_and_process_noise_by_hand():
    A, B = transition_matrices(1, 0.5)
    np.testing.assert_array_equal(A, [[1.0, 0.5], [0.0, 1.0]])
    np.testing.assert_array_equal(B, [0.125, 0.5])
    np.testing.assert_allclose(process_noise(1, 0.5, 2.0), 4.0 * np.outer([0.125, 0.5], [0.125, 0.5]))
    np.testing.assert_allclose(noise_matrix(2, 0.5, 0.1, "identity"), 0.01 * np.eye(3), rtol=1e-15)


@pytest.mark.parametrize("order, dt, match", [
    (-1, 1.0, r"order: expected an integer ≥ 0, got -1"),
    (1.5, 1.0, r"order: expected an integer ≥ 0, got 1.5"),
    (True, 1.0, r"order: expected an integer ≥ 0, got True"),
    (1, 0.0, r"dt: expected a finite time step > 0, got 0.0"),
    (1, float("nan"), r"dt: expected a finite time step > 0, got nan"),
])
def test_transition_rejects_bad_order_or_step(order, dt, match):
    with pytest.raises(ValueError, match=match) as caught:
        transition_matrices(order, dt)
    assert not isinstance(caught.value, ConfigError)  # an algorithm names its own argument


def test_noise_matrix_rejects_unknown_model():
    with pytest.raises(ValueError, match=r"^model: expected one of identity, taylor; got 'white'$") as caught:
        noise_matrix(1, 1.0, 0.1, "white")
    assert not isinstance(caught.value, ConfigError)
    with pytest.raises(ValueError, match=r"^noise: expected one of identity, taylor; got 'white'$") as caught:
        MotionModel(1, 1, 0.1, "white")
    assert not isinstance(caught.value, ConfigError)


def test_motion_model_is_kronecker_lifted_per_axis():
    F, Q = MotionModel(order=1, dof=3, sigma_eta=2.0).matrices(0.5)
    q, v = np.array([1.0, 2.0, 3.0]), np.array([0.1, -0.2, 0.4])
    np.testing.assert_allclose(F @ np.concatenate([q, v]), np.concatenate([q + 0.5 * v, v]))
    # Per axis: B = [dt²/2, dt] so Q = σ² [[dt⁴/4, dt³/2], [dt³/2, dt²]].
    np.testing.assert_allclose(Q[0, 0], 4.0 * 0.5 ** 4 / 4)
    np.testing.assert_allclose(Q[0, 3], 4.0 * 0.5 ** 3 / 2)
    assert Q[0, 1] == 0.0  # axes are independent
    np.testing.assert_allclose(MotionModel(2, 1, 0.1, "identity").matrices(3.0)[1], 0.01 * np.eye(3), rtol=1e-15)


def test_motion_model_caches_read_only_matrices_per_step():
    model = MotionModel(order=2, dof=2, sigma_eta=0.3)
    F, Q = model.matrices(0.25)
    assert model.matrices(0.25)[0] is F and model.matrices(0.25)[1] is Q
    assert model.matrices(0.5)[0] is not F
    A, _ = transition_matrices(2, 0.25)
    np.testing.assert_array_equal(F, np.kron(A, np.eye(2)))
    np.testing.assert_array_equal(Q, np.kron(process_noise(2, 0.25, 0.3), np.eye(2)))
    assert model.size == 6
    with pytest.raises(ValueError, match="read-only"):
        F[0, 0] = 2.0


@pytest.mark.parametrize("kwargs, error, match", [
    ({"order": -1}, ValueError, r"order: expected an integer ≥ 0, got -1"),
    ({"order": 1, "dof": 0}, ValueError, r"dof: expected an integer ≥ 1, got 0"),
    ({"order": 1, "sigma_eta": -0.1}, ValueError, r"sigma_eta: expected a finite number ≥ 0, got -0.1"),
    ({"order": 1, "sigma_eta": float("nan")}, ValueError, r"sigma_eta: expected a finite number ≥ 0, got nan"),
])
def test_motion_model_rejects_bad_arguments(kwargs, error, match):
    with pytest.raises(error, match=match) as caught:
        MotionModel(**kwargs)
    assert not isinstance(caught.value, ConfigError)
    if kwargs == {"order": 1, "dof": 0}:
        return
    with pytest.raises(ValueError, match=r"dt: expected a finite time step > 0, got 0.0") as caught:
        MotionModel(1, 1, 0.1).matrices(0.0)
    assert not isinstance(caught.value, ConfigError)


def test_initial_state_of_a_ramp_is_exact_at_the_last_sample():
    ramp = 0.3 * np.arange(5.0)
    # The padded Gaussian derivative this replaces halved the slope at the end.
    assert gaussian_filter1d(ramp, 0.6, order=1, mode="nearest")[-1] == pytest.approx(0.1465, abs=1e-4)
    # Exact to round-off: the local fit reproduces any line (values ≤ 1.2, so 1e-12).
    for order in (1, 2, 3):
        x = initial_state(ramp, order, 1.0, 0.6)
        np.testing.assert_allclose(x[:2], [1.2, 0.3], atol=1e-12)
        np.testing.assert_allclose(x[2:], 0.0, atol=1e-11)


def test_initial_state_of_a_parabola_is_exact_at_the_last_sample():
    dt = 0.5
    t = dt * np.arange(6)
    q = 2.0 + 0.3 * t - 0.7 * t**2  # q(2.5) = −1.625, q'(2.5) = −3.2, q'' = −1.4
    np.testing.assert_allclose(initial_state(q, 2, dt, 0.6), [-1.625, -3.2, -1.4], atol=1e-11)
    # Order 1 fits a line by default; asking for degree 2 makes its slope exact too.
    np.testing.assert_allclose(initial_state(q, 1, dt, 0.6, degree=2), [-1.625, -3.2], atol=1e-11)


def test_initial_state_of_short_windows():
    np.testing.assert_array_equal(initial_state([0.4], 2, 1.0, 0.6), [0.4, 0.0, 0.0])
    # Two samples: a line through them, no curvature.
    np.testing.assert_allclose(initial_state([0.4, 0.7], 2, 1.0, 0.6), [0.7, 0.3, 0.0], atol=1e-12)
    with pytest.raises(DegenerateFitError, match="the window is empty"):
        initial_state([], 1, 1.0, 0.6)


def test_derivative_operator_on_uneven_times_is_exact_for_a_cubic():
    t = np.array([0.0, 0.4, 1.1, 1.5, 2.6, 3.0])
    q = 1.0 - t + 0.5 * t**2 - 0.2 * t**3
    L = derivative_operator(t, 3, 1.0)
    expected = [1 - 3 + 0.5 * 9 - 0.2 * 27, -1 + 3.0 - 0.6 * 9, 1.0 - 1.2 * 3, -1.2]
    np.testing.assert_allclose(L @ q, expected, atol=1e-9)  # cubic terms up to 27·0.2: 1e-9 is round-off


@pytest.mark.parametrize("times, sigma, error, match", [
    ([0.0], 1.0, DegenerateFitError, "at least 2 samples"),
    ([0.0, 1.0, 1.0], 1.0, DegenerateFitError, "strictly increasing"),
    ([0.0, 1.0, 2.0], 0.0, ValueError, "sigma_time: expected a width > 0"),
])
def test_derivative_operator_rejects_bad_windows(times, sigma, error, match):
    with pytest.raises(error, match=match):
        derivative_operator(times, 1, sigma)


def test_window_fits_name_their_own_width_and_degree():
    with pytest.raises(ValueError, match=r"^smoothing_sigma: expected a width > 0, got 0.0$"):
        initial_state([0.1, 0.2, 0.3], 1, 0.5, 0.0)
    with pytest.raises(ValueError, match=r"^smoothing_sigma: expected a width > 0, got -1.0$"):
        initial_covariance(3, 1, 0.5, -1.0, 0.1)
    with pytest.raises(ValueError, match=r"^degree: expected an integer ≥ 0, got -1$"):
        derivative_operator([0.0, 1.0, 2.0], 1, 1.0, degree=-1)


def test_initial_covariance_matches_the_spread_of_initial_states():
    rng = np.random.default_rng(3)
    sigma_obs, n, draws = 0.2, 7, 20000
    states = np.array([initial_state(sigma_obs * rng.standard_normal(n), 2, 0.5, 1.2) for _ in range(draws)])
    P = initial_covariance(n, 2, 0.5, 1.2, sigma_obs)
    # A sample variance of 20000 Gaussian draws has relative standard error
    # √(2/19999) ≈ 1%; 5% is five of them.
    np.testing.assert_allclose(np.var(states, axis=0), np.diag(P), rtol=0.05)
    assert np.all(np.linalg.eigvalsh(P) > 0)


@settings(max_examples=40, deadline=None)
@given(order=st.integers(min_value=0, max_value=5),
       coefficients=st.lists(st.floats(min_value=-1.0, max_value=1.0), min_size=6, max_size=6),
       dt=st.floats(min_value=0.2, max_value=1.0))
def test_a_polynomial_of_degree_k_is_predicted_exactly_by_order_k(order, coefficients, dt):
    c = np.array(coefficients[: order + 1])
    times = dt * np.arange(25)

    def derivative(d, t):
        return sum(c[j] * factorial(j) / factorial(j - d) * t ** (j - d) for j in range(d, order + 1))

    q = derivative(0, times)
    start = 3
    x0 = np.array([derivative(d, times[start]) for d in range(order + 1)])
    result = filter_trace(times, q, x0, np.eye(order + 1), start, 0.3, 0.01, horizon=4)
    # Exact Taylor propagation and zero innovations keep every prediction on the
    # polynomial; |q| ≤ 6·24⁵ ≈ 5e7 at most, so the tolerance is relative.
    scale = 1.0 + np.abs(q)
    for h in range(4):
        rows = slice(start + h + 1, None)
        np.testing.assert_allclose(result.predicted[rows, h] / scale[rows], q[rows] / scale[rows], atol=1e-9)
    np.testing.assert_allclose(result.states[start:, 0] / scale[start:], q[start:] / scale[start:], atol=1e-9)


def _noisy_trace(n=30, seed=11):
    rng = np.random.default_rng(seed)
    times = np.arange(n, dtype=float)
    return times, np.sin(0.3 * times) + 0.1 * rng.standard_normal(n)


def _filterpy_trace(times, z, x0, P0, start, sigma_eta, R, noise_model, horizon):
    """filter_trace's quantities computed by filterpy's KalmanFilter, step by step."""
    order = x0.size - 1
    reference = KalmanFilter(dim_x=order + 1, dim_z=1)
    reference.x, reference.P = x0.copy(), P0.copy()
    reference.H, reference.R = observation_matrix(order), np.array([[R]])
    n = z.size
    states = np.full((n, order + 1), np.nan)
    variances = np.full((n, order + 1), np.nan)
    log_likelihood = np.full(n, np.nan)
    nis = np.full(n, np.nan)
    predicted = np.full((n, horizon), np.nan)

    def store(i):
        states[i], variances[i] = reference.x, np.diag(reference.P)
        x = reference.x
        for h in range(1, min(horizon, n - 1 - i) + 1):  # step by step: A(a) A(b) = A(a + b)
            x = transition_matrices(order, times[i + h] - times[i + h - 1])[0] @ x
            predicted[i + h, h - 1] = x[0]

    store(start)
    for i in range(start + 1, n):
        dt = times[i] - times[i - 1]
        reference.F, _ = transition_matrices(order, dt)
        reference.Q = noise_matrix(order, dt, sigma_eta, noise_model)
        reference.predict()
        reference.update(z[i])
        log_likelihood[i] = reference.log_likelihood
        nis[i] = reference.y[0] ** 2 / reference.S[0, 0]  # y'S^-1y of the scalar innovation
        store(i)
    return states, variances, log_likelihood, nis, predicted


@pytest.mark.parametrize("order, noise_model", [(0, "taylor"), (1, "taylor"), (2, "identity"), (3, "taylor")])
def test_trace_filter_agrees_with_filterpy(order, noise_model):
    times, z = _noisy_trace()
    times = times + 0.3 * np.sin(times)  # uneven steps (all > 0): every step has its own F and Q
    start = 4
    x0 = initial_state(z[: start + 1], order, 1.0, 0.6)
    P0 = np.diag(np.arange(1.0, order + 2.0))
    result = filter_trace(times, z, x0, P0, start, 0.2, 0.01, noise_model=noise_model, horizon=3)
    states, variances, log_likelihood, nis, predicted = _filterpy_trace(times, z, x0, P0, start, 0.2, 0.01,
                                                                        noise_model, 3)
    # Same equations (Joseph form) in a different order of operations: round-off
    # only, entries of order 1 (the variances and predictions too), so 1e-12.
    np.testing.assert_allclose(result.states, states, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(result.variances, variances, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(result.predicted, predicted, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(result.log_likelihood, log_likelihood, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(result.nis, nis, rtol=1e-12, atol=1e-12)
    assert np.all(np.isnan(result.states[:start])) and np.all(np.isnan(result.log_likelihood[: start + 1]))


def test_trace_with_uneven_steps_uses_each_step():
    times = np.array([0.0, 1.0, 2.0, 2.5, 4.0, 4.2])
    q = 0.5 + 0.8 * times  # a ramp is exact for order 1 whatever the steps
    result = filter_trace(times, q, [0.5 + 0.8 * 2.0, 0.8], np.eye(2), 2, 0.1, 0.01, horizon=3)
    np.testing.assert_allclose(result.predicted[3:, 0], q[3:], atol=1e-12)
    np.testing.assert_allclose(result.predicted[5, 2], q[5], atol=1e-12)


def test_trace_rejects_mismatched_shapes():
    with pytest.raises(ValueError, match=r"times and z must have the same shape"):
        filter_trace(np.arange(5.0), np.zeros(4), [0.0], np.eye(1), 0, 0.1, 0.1)
    with pytest.raises(ValueError, match=r"P0 must have shape \(2, 2\)"):
        filter_trace(np.arange(5.0), np.zeros(5), [0.0, 0.0], np.eye(3), 0, 0.1, 0.1)
    with pytest.raises(ValueError, match=r"need 0 ≤ start < 5"):
        filter_trace(np.arange(5.0), np.zeros(5), [0.0], np.eye(1), 5, 0.1, 0.1)
