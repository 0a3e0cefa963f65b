"""Generated spring-loaded door traces (SPEC 8.2)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.config.sim import door_scenario_from_config
from stslam.sim.door_trace import DoorModel, Push, door_angles, generate_trace
from conftest import compose_config


@pytest.fixture(scope="module")
def config():
    return compose_config("temporal_order")


@pytest.fixture(scope="module")
def scenario(config):
    return door_scenario_from_config(config)


def _peaks(angles):
    inner = angles[1:-1]
    return inner[(inner > angles[:-2]) & (inner >= angles[2:])]


def test_default_traces_look_like_the_papers(scenario):
    # SPEC 8.2: ~30 samples of two swings between ~0.6 and ~2.5 rad, then ~10 at rest.
    for k in range(10):
        trace = generate_trace(scenario, 1.0, np.random.default_rng(k))
        truth = trace.angles_true
        assert truth.size == 40
        np.testing.assert_array_equal(trace.times, np.arange(40.0))
        assert truth.min() == pytest.approx(0.6, abs=1e-12)  # the frame is the lowest angle
        big = _peaks(truth)[_peaks(truth) > 1.5]
        assert big.size == 2
        assert np.all((big > 2.1) & (big < 2.95))
        np.testing.assert_allclose(truth[-9:], 0.6, atol=1e-3)  # shut and still at the end


def test_the_frame_is_a_hard_stop():
    model = DoorModel(restitution=0.0)
    t = np.arange(0.0, 30.0, 0.25)
    theta = door_angles(t, model, [Push(1.0, 0.5, 1.8)])
    assert theta.min() >= model.closed_angle
    # Inelastic stop: once back at the frame the spring preload keeps it there.
    back = np.argmax((t > 5.0) & (theta <= model.closed_angle + 1e-12))
    np.testing.assert_array_equal(theta[back:], model.closed_angle)


def test_without_pushes_the_door_stays_shut():
    theta = door_angles(np.arange(20.0), DoorModel(), [])
    np.testing.assert_array_equal(theta, DoorModel().closed_angle)


def test_elastic_undamped_door_bounces_back_to_the_same_height():
    # With e = 1 and ζ = 0 the spring energy is conserved after the push ends,
    # so every swing peaks at the same angle; semi-implicit Euler with 1 ms
    # steps keeps energy to O(h) ≈ 1e-3 relative, hence a 0.01 rad tolerance.
    model = DoorModel(damping_ratio=0.0, restitution=1.0)
    theta = door_angles(np.arange(0.0, 60.0, 0.05), model, [Push(0.5, 0.5, 1.8, max_s=6.0)], step_s=0.001)
    peaks = _peaks(theta)
    peaks = peaks[peaks > 1.0]  # swings, not the shut door before the push
    assert peaks.size >= 3
    np.testing.assert_allclose(peaks, peaks[0], atol=0.01)


def test_noise_and_determinism(scenario):
    a = generate_trace(scenario, 1.0, np.random.default_rng(5))
    b = generate_trace(scenario, 1.0, np.random.default_rng(5))
    c = generate_trace(scenario, 1.0, np.random.default_rng(6))
    np.testing.assert_array_equal(a.angles_observed, b.angles_observed)
    assert not np.array_equal(a.angles_true, c.angles_true)  # pushes differ per seed
    residuals = np.concatenate([generate_trace(scenario, 1.0, np.random.default_rng(k)).angles_observed
                                - generate_trace(scenario, 1.0, np.random.default_rng(k)).angles_true
                                for k in range(25)])
    # 1000 draws of N(0, 0.05²): the sample std has relative standard error
    # 1/√(2·999) ≈ 2.2%; 10% is more than four of them.
    assert residuals.std() == pytest.approx(scenario.noise_sigma, rel=0.10)


def test_jitter_moves_the_pushes_within_their_bounds(scenario):
    for k in range(20):
        pushes = generate_trace(scenario, 1.0, np.random.default_rng(k)).pushes
        for push, nominal in zip(pushes, scenario.pushes):
            assert abs(push.start_s - nominal.start_s) <= scenario.jitter.time_s
            assert abs(push.accel / nominal.accel - 1.0) <= scenario.jitter.accel_frac
            assert abs(push.release_angle - nominal.release_angle) <= scenario.jitter.release_rad
