"""The articulated block's slip: a tracked point that creeps over its part (stslam.slam.blocks)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.articulation.models import get_model
from stslam.config.slam import a_slam_from_config
from stslam.errors import ConfigError
from stslam.robot.sensor import observe
from stslam.sim.worlds import revolute_structure
from stslam.slam import ArticulatedBlock, SlamState

from conftest import compose_config

CIRCLE = revolute_structure([1.5, 0.2, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0], 0.5)


def _block(sigma_slip):
    return ArticulatedBlock(get_model("revolute"), CIRCLE, order=1, sigma_eta=0.3, sigma_rate0=1.0,
                            sigma_slip=sigma_slip)


def _fd(f, x0, h=1e-6):
    return np.column_stack([(f(x0 + h * e) - f(x0 - h * e)) / (2 * h) for e in np.eye(x0.size)])


def test_slip_is_a_random_walk_added_to_the_point_on_the_structure():
    plain, slipping = _block(0.0), _block(0.02)
    assert (plain.size, slipping.size, slipping.motion_size) == (2, 5, 2)
    x_b = np.array([0.4, 0.1, 0.01, -0.02, 0.03])
    m, dm_dx = slipping.position(x_b)
    np.testing.assert_allclose(m, plain.position(x_b[:2])[0] + x_b[2:], atol=1e-15)
    # Central differences (h = 1e-6) on smooth O(1) functions: error ≲ 1e-9.
    np.testing.assert_allclose(dm_dx, _fd(lambda v: slipping.position(v)[0], x_b), atol=1e-8)
    x0, D, prior = slipping.initial(m)
    np.testing.assert_array_equal(x0[2:], 0.0)  # the first point is on the structure
    np.testing.assert_array_equal(D[2:], 0.0)
    np.testing.assert_allclose(prior, np.diag([0.0, 1.0, 0.0, 0.0, 0.0]))
    F, Q = slipping.transition(0.5)
    F0, Q0 = plain.transition(0.5)
    np.testing.assert_array_equal(F[:2, :2], F0)
    np.testing.assert_array_equal(Q[:2, :2], Q0)
    np.testing.assert_array_equal(F[2:, 2:], np.eye(3))
    np.testing.assert_allclose(Q[2:, 2:], 0.02**2 * 0.5 * np.eye(3), rtol=1e-15)
    assert not F[:2, 2:].any() and not Q[:2, 2:].any()


def test_no_slip_leaves_the_block_as_it_was():
    plain = _block(0.0)
    F, Q = plain.transition(0.1)
    assert F is plain.motion.matrices(0.1)[0] and Q is plain.motion.matrices(0.1)[1]
    x_b = np.array([0.4, 0.1])
    np.testing.assert_array_equal(plain.position(x_b)[1][:, 1], 0.0)


def _pose_error(sigma_slip, creep_m_per_s, n=240, dt=1 / 30):
    """Robot x error after a door point turned at 0.5 rad/s while its tracked point crept outwards."""
    pose = np.array([0.0, 0.0, 0.0])
    state = SlamState(pose, np.diag([1e-4, 1e-4, 1e-5]))
    R = (0.005**2) * np.eye(3)
    block = _block(sigma_slip)
    model = get_model("revolute")
    for k in range(n):
        phi = 0.5 * k * dt
        m = model.position(CIRCLE, np.array([phi]))
        m = m + creep_m_per_s * k * dt * (m - CIRCLE.centre_world) / CIRCLE.radius  # along the radius
        z = observe(pose, m.reshape(1, 3))[0]
        if k == 0:
            state.add_landmark(1, block, z, R)
        else:
            state.predict(np.zeros(2), 1e-8 * np.eye(2), dt)
            state.update_landmarks([1], z.reshape(1, 3), R.reshape(1, 3, 3))
    return abs(state.x[0] - pose[0]), float(np.sqrt(state.P[0, 0]))


def test_slip_keeps_a_creeping_track_from_pulling_the_robot():
    # The point creeps 4 cm over 8 s: a fixed circle pulls the robot towards that error and becomes sure
    # of it; the slip takes up the creep, and the robot stays within its own uncertainty.
    fixed_error, fixed_sigma = _pose_error(0.0, 0.005)
    slip_error, slip_sigma = _pose_error(0.02, 0.005)
    assert fixed_error > 3.0 * fixed_sigma
    assert slip_error < 0.5 * fixed_error and slip_error < 3.0 * slip_sigma


@pytest.mark.parametrize("overrides, match", [
    (["filters.a_slam.sigma_slip_m=-0.1"], r"filters\.a_slam\.sigma_slip_m"),
    (["filters.a_slam.sigma_slip_m=0.01", "filters.a_slam.bodies={}"], r"filters\.a_slam\.sigma_slip_m.*bodies"),
    (["backend=isam2", "isam2.structure=variable"], r"filters\.a_slam\.sigma_slip_m.*isam2\.structure"),
])
def test_slip_settings_reject_bad_values(overrides, match):
    with pytest.raises(ConfigError, match=match):
        a_slam_from_config(compose_config("fridge", overrides))


def test_slip_setting_reaches_the_blocks():
    assert a_slam_from_config(compose_config("fridge", ["filters.a_slam.sigma_slip_m=0.01"])).sigma_slip_m == 0.01
    assert a_slam_from_config(compose_config("dynamic_slam", [])).sigma_slip_m == 0.0
    # The fridge's graph keeps its structures fixed (isam2.structure: fixed), so its blocks slip as the EKF's do.
    assert a_slam_from_config(compose_config("fridge", ["backend=isam2"])).sigma_slip_m == 0.1
