"""The covariance A-SLAM gives each point it feeds to selection (SPEC 13)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.errors import ConfigError
from stslam.experiments import dynamic_slam
from stslam.geometry import rotation_z
from stslam.robot.sensor import point_from_observation, world_point_covariances
from stslam.slam.a_slam import selection_covariances
from stslam.slam.blocks import StaticPointBlock
from stslam.slam.core import SlamState
from stslam.slam.loop import Frame

POSE = np.array([1.0, 2.0, 0.7])
POSE_COV = np.diag([0.04, 0.02, 0.01])
Z = np.array([[2.0, 0.5, 0.3], [1.0, -1.0, 0.8]])
R = np.repeat((0.04 ** 2 * np.eye(3))[None], 2, axis=0)


def _state_and_frame():
    state = SlamState(POSE, POSE_COV)
    for i, z in enumerate(Z):
        state.add_landmark(i, StaticPointBlock(0.0), z, R[i])
    return state, Frame(k=1, ids=[0, 1], zs=Z, Rs=R)


def test_pose_covariance_is_the_rotated_sensor_noise_plus_the_pose_share():
    covs = world_point_covariances(POSE, POSE_COV, Z, R)
    for z, r, cov in zip(Z, R, covs):
        _, J_pose, rot = point_from_observation(POSE, z)
        np.testing.assert_allclose(cov, rot @ r @ rot.T + J_pose @ POSE_COV @ J_pose.T, atol=1e-15)


def test_relative_covariance_drops_the_pose_error_a_point_shares_with_its_estimate():
    # A point just placed through this pose carries the pose's error itself: against that
    # estimate, a second sighting from the same pose differs by the sensor noise only
    # (S = R + H P Hᵀ = 2R, the pose terms cancel), however uncertain the pose.
    state, frame = _state_and_frame()
    relative = selection_covariances(state, frame, [0, 1], "relative")
    pose = selection_covariances(state, frame, [0, 1], "pose")
    rot = rotation_z(POSE[2])
    for j in range(2):
        np.testing.assert_allclose(relative[j], 2 * rot @ R[j] @ rot.T, atol=1e-12)
        assert np.linalg.eigvalsh(pose[j])[-1] > 10 * np.linalg.eigvalsh(relative[j])[-1]
    assert selection_covariances(state, frame, [1], "sensor") == [None]
    assert selection_covariances(state, frame, [], "relative") == []


def test_an_unknown_selection_covariance_is_a_config_error(compose_exp):
    cfg = compose_exp("dynamic_slam", "n_seeds=1", "methods=[a_slam]", "filters.a_slam.selection_covariance=full")
    with pytest.raises(ConfigError, match="filters.a_slam.selection_covariance"):
        dynamic_slam.run(cfg)


class _Mark:
    def __init__(self, status):
        self.status = status


def _consensus_case(world_shifts):
    """Six decided-static points mapped while the robot was certain, now seen from a pose known to
    ±5 cm, each as if it had moved by its world shift (m); outcome j → used."""
    from scipy.stats import chi2

    from stslam.slam.a_slam import _update
    R = 0.02 ** 2 * np.eye(3)
    zs = np.array([[2.0, -1.0, 0.5], [2.5, 0.0, 1.0], [2.0, 1.0, 0.3], [3.0, -0.5, 1.2], [3.0, 0.6, 0.8],
                   [2.2, 0.2, 1.5]])
    state = SlamState(np.zeros(3), np.zeros((3, 3)))
    for i, z in enumerate(zs):
        state.add_landmark(i, StaticPointBlock(0.0), z, R)
    state.P[:3, :3] += np.diag([0.05 ** 2, 0.05 ** 2, 1e-6])  # the robot has moved since (θ = 0: robot = world axes)
    marks = {i: _Mark("static") for i in range(len(zs))}
    return _update(state, list(range(len(zs))), zs + np.asarray(world_shifts), np.repeat(R[None], len(zs), axis=0),
                   marks, set(), float(chi2.ppf(0.99, 3)), 0.99)


def test_points_that_fail_the_gate_together_are_used_when_one_robot_correction_explains_them():
    # Every point appears 0.3 m further along x: the robot is off by more than its 5 cm, not they.
    outcome = _consensus_case(np.tile([0.3, 0.0, 0.0], (6, 1)))
    assert all(outcome.values())


def test_points_that_fail_the_gate_together_but_disagree_are_not_used():
    # Four points appear 0.3 m along x (a drawer's front, called static while it rested), two stay:
    # a trial update pulled by the four fits them (NIS ≈ 5 each), not the two (≈ 14), and their sum
    # (≈ 48) fails χ²₁₈ at 99% (34.8): no single robot correction explains them, the gate's verdict
    # stands. (Taking the four that fit would follow the drawer.)
    shifts = np.array([[0.3, 0.0, 0.0]] * 4 + [[0.0, 0.0, 0.0]] * 2)
    outcome = _consensus_case(shifts)
    assert not any(outcome[j] for j in range(4)) and outcome[4] and outcome[5]
