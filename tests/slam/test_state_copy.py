"""SlamState.copy: the independent state A-SLAM's consensus check runs its trial update on (SPEC 6.3)."""

from __future__ import annotations

import numpy as np

from stslam.robot.sensor import observe
from stslam.slam.blocks import ConstantVelocityPointBlock, StaticPointBlock
from stslam.slam.core import SlamState

R = 0.04**2 * np.eye(3)
LANDMARKS = np.array([[2.0, 0.5, 0.3], [1.5, -1.0, 0.1], [3.0, 1.2, 0.6]])


def _state_with_two_blocks():
    state = SlamState(np.array([0.2, -0.1, 0.3]), 0.01 * np.eye(3))
    state.add_landmark(0, StaticPointBlock(0.01), observe(state.pose, LANDMARKS[0]), R)
    state.add_landmark(1, ConstantVelocityPointBlock(0.01, 0.1), observe(state.pose, LANDMARKS[1]), R)
    state.predict(np.array([0.2, 0.05]), np.diag([1e-4, 1e-4]), 1.0)
    return state


def test_updating_a_copy_leaves_the_original_unchanged():
    state = _state_with_two_blocks()
    x, P, ids = state.x.copy(), state.P.copy(), state.landmark_ids
    zs = np.array([observe(state.pose, LANDMARKS[i]) + 0.05 for i in (0, 1)])
    trial = state.copy()
    trial.update_landmarks([0, 1], zs, R)
    trial.update_landmark(0, zs[0], R)
    trial.predict(np.array([0.2, 0.05]), np.diag([1e-4, 1e-4]), 0.5)  # a new δt: new prediction caches
    trial.add_landmark(2, StaticPointBlock(0.0), observe(trial.pose, LANDMARKS[2]), R)
    trial.remove_landmark(0)
    assert not np.array_equal(trial.x[:3], x[:3])
    np.testing.assert_array_equal(state.x, x)
    np.testing.assert_array_equal(state.P, P)
    assert state.landmark_ids == ids and state.indices(1).tolist() == list(range(6, 12))
    # The original still predicts and updates as if the copy had never existed.
    fresh = _state_with_two_blocks()
    for s in (state, fresh):
        s.predict(np.array([0.2, 0.05]), np.diag([1e-4, 1e-4]), 1.0)
        s.update_landmarks([0, 1], zs, R)
    np.testing.assert_array_equal(state.x, fresh.x)
    np.testing.assert_array_equal(state.P, fresh.P)


def test_a_copy_updates_exactly_as_its_original_and_shares_its_blocks():
    state = _state_with_two_blocks()
    trial = state.copy()
    assert trial.block(1) is state.block(1)  # immutable blocks are shared, not copied
    assert trial.motion_order == state.motion_order and trial.update_iterations == state.update_iterations
    zs = np.array([observe(state.pose, LANDMARKS[i]) + 0.02 for i in (0, 1)])
    a, _ = state.update_landmarks([0, 1], zs, R, max_nis=11.34)
    b, _ = trial.update_landmarks([0, 1], zs, R, max_nis=11.34)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(trial.x, state.x)
    np.testing.assert_array_equal(trial.P, state.P)
