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
