"""A-SLAM's articulated observations one by one or in one update (ASlamParams.articulated_update)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.articulation.models import get_model
from stslam.config.slam import a_slam_from_config
from stslam.errors import ConfigError
from stslam.robot.sensor import observe
from stslam.sim.worlds import revolute_structure
from stslam.slam import SlamState, StaticPointBlock
from stslam.slam.a_slam import _update
from stslam.slam.blocks import ArticulatedBlock

from conftest import compose_config

R = 0.02 ** 2 * np.eye(3)


class _Mark:
    def __init__(self, status):
        self.status, self.r_scale = status, 1.0


def _frame():
    """A state with two static points and three door points on one hinge, and a frame of their observations: the
    door turned on 0.1 rad, the last door point's observation 1 m off (the gate turns it away)."""
    state = SlamState(np.array([0.0, 0.0, 0.2]), np.diag([0.05 ** 2, 0.05 ** 2, 0.01 ** 2]))
    statics = {1: np.array([2.0, -1.0, 0.5]), 2: np.array([2.5, 1.0, 1.0])}
    for i, m in statics.items():
        state.add_landmark(i, StaticPointBlock(0.0), observe(state.pose, m), R)
    doors = {}
    for i, radius in ((5, 0.4), (6, 0.6), (7, 0.8)):
        block = ArticulatedBlock(get_model("revolute"), revolute_structure(np.array([3.0, 0.0, 0.0]), np.array(
            [0.0, 0.0, 1.0]), [1.0, 0.0, 0.0], radius), 1, 0.01, 0.1)
        doors[i] = block.model.position(block.structure, np.array([0.4]))
        state.add_landmark(i, block, observe(state.pose, block.model.position(block.structure, np.array([0.3]))), R)
    ids = [1, 2, 5, 6, 7]
    zs = np.array([observe(state.pose, m) for m in [*statics.values(), *doors.values()]])
    zs[4] += [1.0, 0.0, 0.0]
    marks = {1: _Mark("static"), 2: _Mark("static"), 5: _Mark("revolute"), 6: _Mark("revolute"), 7: _Mark("revolute")}
    return state, ids, zs, np.repeat(R[None], 5, axis=0), marks


def test_joint_gates_each_against_the_static_points_posterior_and_updates_the_accepted_together():
    state, ids, zs, Rs, marks = _frame()
    expected = state.copy()
    expected.update_landmarks([1, 2], zs[:2], Rs[:2])
    accepted, _ = expected.update_landmarks([5, 6, 7], zs[2:], Rs[2:], 16.0)
    one_by_one = state.copy()
    each = _update(one_by_one, ids, zs, Rs, marks, set(), 16.0, 0.999)
    joint = _update(state, ids, zs, Rs, marks, set(), 16.0, 0.999, joint=True)
    assert accepted.tolist() == [True, True, False]
    assert joint == each == {0: True, 1: True, 2: True, 3: True, 4: False}
    np.testing.assert_array_equal(state.x, expected.x)
    np.testing.assert_array_equal(state.P, expected.P)
    # one by one, the second door point is gated and linearised at the state the first left: another result
    assert not np.array_equal(one_by_one.x, state.x)
    np.testing.assert_allclose(one_by_one.x, state.x, atol=5e-3)


def test_the_setting_is_read_and_checked():
    assert a_slam_from_config(compose_config("dynamic_slam", [])).articulated_update == "each"
    assert a_slam_from_config(compose_config("fridge", [])).articulated_update == "joint"
    bad = compose_config("dynamic_slam", ["filters.a_slam.articulated_update=together"])
    with pytest.raises(ConfigError, match=r"filters\.a_slam\.articulated_update: expected one of each, joint"):
        a_slam_from_config(bad)
