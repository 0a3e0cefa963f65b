"""Temporal models (SPEC 3) and the order-k Kalman filter of a directly observed q (SPEC 8.2)."""

from __future__ import annotations

from math import factorial

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from hypothesis import given, settings, strategies as st
from scipy.linalg import expm
from scipy.ndimage import gaussian_filter1d

from stslam.errors import ConfigError, DegenerateFitError
from stslam.kalman.trace_filter import MotionFilter, filter_trace, noise_matrix, observation_matrix
from stslam.kalman.temporal import (derivative_operator, initial_covariance, initial_state, process_noise,
                             transition_matrices)

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
    with pytest.raises(ConfigError, match=match):
        transition_matrices(order, dt)


def test_noise_matrix_rejects_unknown_model():
    with pytest.raises(ConfigError, match=r"process_noise: expected one of identity, taylor; got 'white'"):
        noise_matrix(1, 1.0, 0.1, "white")


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
    ([0.0, 1.0, 2.0], 0.0, ConfigError, "smoothing_sigma: expected a width > 0"),
])
def test_derivative_operator_rejects_bad_windows(times, sigma, error, match):
    with pytest.raises(error, match=match):
        derivative_operator(times, 1, sigma)


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


@pytest.mark.parametrize("order, noise_model", [(0, "taylor"), (1, "taylor"), (2, "identity"), (3, "taylor")])
def test_motion_filter_agrees_with_filterpy(order, noise_model):
    times, z = _noisy_trace()
    x0 = initial_state(z[:5], order, 1.0, 0.6)
    P0 = np.diag(np.arange(1.0, order + 2.0))
    ours = MotionFilter(x0, P0, 1.0, 0.2, 0.01, noise_model)
    reference = KalmanFilter(dim_x=order + 1, dim_z=1)
    reference.x, reference.P = x0.copy(), P0.copy()
    reference.F, reference.Q = ours.F.copy(), ours.Q.copy()
    reference.H, reference.R = observation_matrix(order), np.array([[0.01]])
    for value in z[5:]:
        ours.predict()
        reference.predict()
        log_likelihood = ours.update(value)
        reference.update(value)
        # Same equations (Joseph form) in a different order of operations:
        # round-off only, entries of order 1, so 1e-12.
        np.testing.assert_allclose(ours.x, reference.x, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ours.P, reference.P, rtol=1e-12, atol=1e-12)
        assert log_likelihood == pytest.approx(reference.log_likelihood, rel=1e-12, abs=1e-12)


def test_trace_function_and_class_agree():
    times, z = _noisy_trace()
    order, start = 2, 4
    x0 = initial_state(z[: start + 1], order, 1.0, 0.6)
    P0 = initial_covariance(start + 1, order, 1.0, 0.6, 0.1)
    result = filter_trace(times, z, x0, P0, start, 0.2, 0.01, horizon=3)
    stepper = MotionFilter(x0, P0, 1.0, 0.2, 0.01)
    ahead = {start + h: stepper.predict_ahead(h)[0][0] for h in (1, 2, 3)}
    for i in range(start + 1, times.size):
        stepper.predict()
        np.testing.assert_allclose(result.predicted[i, 0], stepper.x[0], rtol=1e-12)
        log_likelihood = stepper.update(z[i])
        np.testing.assert_allclose(result.states[i], stepper.x, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(result.variances[i], np.diag(stepper.P), rtol=1e-12)
        assert result.log_likelihood[i] == pytest.approx(log_likelihood, rel=1e-12)
    # predict_ahead (repeated F) and the trace's A(hδt) give the same forecasts.
    for i, value in ahead.items():
        assert result.predicted[i, i - start - 1] == pytest.approx(value, rel=1e-12)
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
