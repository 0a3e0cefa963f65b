"""A body member's own offset error as a consider parameter (SPEC 13, structure_state: consider)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.articulation.models import get_model
from stslam.geometry import rotation_about_axis
from stslam.robot.sensor import observe
from stslam.sim.worlds import revolute_structure
from stslam.slam.blocks import ArticulatedBlock, CorrectedArticulatedBlock, StaticPointBlock
from stslam.slam.bodies.joint import BodyJoint, member_offset, member_offset_covariance, member_position, \
    member_structure
from stslam.slam.bodies.state import BodySlamState, OffsetKey

HINGE = BodyJoint("revolute", np.array([1.5, 2.0, 0.0]), np.array([0.0, 0.0, 1.0]))
OFFSET_COV = np.diag([4e-4, 1e-4, 2e-4])


def _body(offset_cov=OFFSET_COV):
    """A consider-δ revolute founder (7) at φ = 0.3 and a member (8) with an offset error of ``offset_cov``."""
    state = BodySlamState(np.array([0.0, 0.0, 0.2]), 1e-4 * np.eye(3))
    structure = revolute_structure(HINGE.point, HINGE.direction, [1.0, 0.0, 0.0], 0.8)
    plain = ArticulatedBlock(get_model("revolute"), structure, 1, 0.01, 0.1)
    state.add_landmark(7, plain, observe(state.pose, plain.model.position(structure, np.array([0.3]))),
                       0.02 ** 2 * np.eye(3))
    founder = CorrectedArticulatedBlock(plain.model, structure, 1, 0.01, 0.1, consider=True)
    J = np.vstack([np.eye(2), np.zeros((6, 2))])
    prior = np.zeros((8, 8))
    prior[2:, 2:] = 1e-4 * np.eye(6)
    state.replace_block(7, founder, J @ state.block_mean(7), J, prior)
    handle = member_structure(HINGE, HINGE.point + np.array([0.7, 0.0, -0.2]))
    state.add_member(8, 7, founder.member_view(handle), offset_cov)
    return state, founder


def test_the_offset_error_is_a_consider_parameter_read_by_the_member_only():
    state, founder = _body()
    assert set(state.landmark_ids) == {7, 8} and state.founder_ids() == [7]
    idx = state.indices(8)
    np.testing.assert_array_equal(idx[:founder.size], state.indices(7))
    assert idx.size == founder.size + 3 and set(idx[-3:]) <= set(state.frozen())
    np.testing.assert_allclose(state.P[np.ix_(idx[-3:], idx[-3:])], OFFSET_COV)
    # H by numerical differences over the whole state: ε enters turned by R(â, φ) with the body.
    z_hat, cols, H = state.predict_observation(8)
    full = np.zeros((3, state.x.size))
    full[:, cols] = H
    numeric = np.zeros_like(full)
    for c in range(state.x.size):
        dx = np.zeros(state.x.size)
        dx[c] = 1e-7
        numeric[:, c] = (state.predict_observation(8, state.x + dx)[0] - z_hat) / 1e-7
    np.testing.assert_allclose(full, numeric, atol=1e-5)
    # The member's position is as uncertain as the body's, plus the offset turned with it.
    _, cov = state.landmark_position(8)
    without, _ = _body(None)
    _, cov0 = without.landmark_position(8)
    turn = rotation_about_axis(HINGE.direction, state.x[state.indices(7)[0]])
    np.testing.assert_allclose(cov - cov0, turn @ OFFSET_COV @ turn.T, atol=1e-12)
    # An update moves q but leaves ε (a consider parameter) at zero.
    z = z_hat + np.array([0.02, -0.01, 0.0])
    before = state.x[state.indices(7)[0]]
    assert state.update_landmark(8, z, 0.02 ** 2 * np.eye(3)).accepted
    assert state.x[state.indices(7)[0]] != before
    np.testing.assert_array_equal(state.x[state.indices(8)[-3:]], 0.0)


def test_a_leaving_member_takes_its_offset_error_into_its_point():
    state, founder = _body()
    m, cov = state.landmark_position(8)
    state.detach_member(8, StaticPointBlock(0.0))
    assert OffsetKey(8) not in state._blocks and state.x.size == 3 + founder.size + 3
    m_after, cov_after = state.landmark_position(8)
    np.testing.assert_allclose(m_after, m, atol=1e-12)
    np.testing.assert_allclose(cov_after, cov, atol=1e-12)
    assert np.linalg.eigvalsh(state.P).min() > -1e-12
    # Removing a member drops its offset error as well.
    state, _ = _body()
    state.remove_landmark(8)
    assert 8 not in state and OffsetKey(8) not in state._blocks and state.x.size == 3 + founder.size


def test_a_view_that_cannot_read_the_offset_drops_it():
    state, founder = _body()
    plain = CorrectedArticulatedBlock(founder.model, founder.structure, 1, 0.01, 0.1, consider=False)
    state.set_member_block(8, plain.member_view(state.block(8).structure))
    assert OffsetKey(8) not in state._blocks and state.indices(8).size == founder.size
    state, founder = _body()
    state.set_member_block(8, founder.member_view(state.block(8).structure))  # re-anchored: kept
    assert state.block(8).member_offset and state.indices(8).size == founder.size + 3


def _draws(joint, p_zero, qs, sensor_cov, rng, n_draws):
    """p_zero by member_offset from noisy points at angles qs, n_draws times."""
    exact = np.array([member_position(joint, p_zero, 0.0, q) for q in qs])
    noise = rng.multivariate_normal(np.zeros(3), sensor_cov, size=(n_draws, qs.size))
    return np.array([member_offset(joint, exact + e, qs) for e in noise])


@pytest.mark.parametrize("model", ["revolute", "prismatic"])
def test_the_offset_covariance_matches_the_spread_of_the_fitted_offset(model):
    # Sensor noise only (independent between frames): member_offset's spread over many draws. 4000 draws
    # give each variance to about ±2·√(2/4000) ≈ ±4.5% (two standard errors): 10% is outside that.
    joint = HINGE if model == "revolute" else BodyJoint("prismatic", np.zeros(3), np.array([0.6, 0.8, 0.0]))
    p_zero, qs = np.array([2.3, 2.1, 0.4]), np.linspace(0.0, 0.9, 12)
    sensor = np.array([[9e-4, 2e-4, 0.0], [2e-4, 4e-4, 0.0], [0.0, 0.0, 1e-4]])
    draws = _draws(joint, p_zero, qs, sensor, np.random.default_rng(3), 4000)
    predicted = member_offset_covariance(joint, qs, np.broadcast_to(sensor, (12, 3, 3)), np.zeros((12, 3, 3)))
    np.testing.assert_allclose(np.diag(np.cov(draws.T)), np.diag(predicted), rtol=0.10)
    # The pose's share is one slowly varying error over the window: it is not averaged down.
    pose = 1e-3 * np.eye(3)
    with_pose = member_offset_covariance(joint, qs, np.zeros((12, 3, 3)), np.broadcast_to(pose, (12, 3, 3)))
    if model == "prismatic":
        np.testing.assert_allclose(with_pose, pose, atol=1e-15)
    assert np.trace(with_pose) == pytest.approx(np.trace(pose), rel=1e-12)  # turned, not shrunk
    with pytest.raises(ValueError, match="qs, sensor_covs, pose_covs"):
        member_offset_covariance(joint, qs, np.zeros((11, 3, 3)), np.zeros((12, 3, 3)))
