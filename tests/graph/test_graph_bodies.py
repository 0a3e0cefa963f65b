"""Bodies in the iSAM2 state (SPEC 13, 14): a member's observations update its founder's motion state,
exactly as in the EKF's BodySlamState on a linear-Gaussian problem."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

pytest.importorskip("gtsam")

from stslam.slam.bodies.joint import joint_of, member_structure  # noqa: E402
from stslam.articulation.models import PrismaticStructure, get_model  # noqa: E402
from stslam.graph.bodies import GraphBodyState  # noqa: E402
from stslam.graph.state import Isam2Settings  # noqa: E402
from stslam.slam.bodies.grouping import _member_block  # noqa: E402
from stslam.slam.bodies.state import BodySlamState  # noqa: E402
from stslam.slam.blocks import ArticulatedBlock, StaticPointBlock  # noqa: E402
from linear_scene import straight_line_inputs  # noqa: E402
from stslam.slam.loop import BlockPolicy, run_slam  # noqa: E402

AXIS = np.array([1.0, 0.0, 0.0])
DRAWER = PrismaticStructure(p0=np.array([1.5, 1.0, 0.4]), direction=AXIS, residual_m=0.0)
HANDLE_AT_ZERO = np.array([1.5, 1.3, 0.6])  # the member's position at q = 0
CONVERT_AT, JOIN_AT, LEAVE_AT = 3, 5, 11


def _inputs(seed=0, n=16):
    """On a straight line (linear_scene) every model with a prismatic joint is linear in the state. Points 0-2 are
    static; 4 (founder) and 5 (member) move together along x by 0.02 m per frame."""
    static = np.array([[1.0, 1.0, 0.2], [2.0, -1.0, 0.5], [1.5, 0.5, 0.0]])

    def world_at(k):
        q = 0.02 * k
        world = {0: static[0], 1: static[1], 2: static[2], 4: DRAWER.p0 + q * AXIS}
        if k >= JOIN_AT:
            world[5] = HANDLE_AT_ZERO + q * AXIS
        seen = sorted(world)
        return seen, np.array([world[i] for i in seen])

    return straight_line_inputs(world_at, n, 0.03, seed)


@dataclass(frozen=True)
class _BodyScript(BlockPolicy):
    """Static points; landmark 4 converted to a prismatic block at CONVERT_AT; 5 joins its body at first
    sight and, with ``leave``, leaves it as a static point after LEAVE_AT (the state calls A-SLAM's
    policy makes)."""

    leave: bool = True

    def before_update(self, state, frame) -> set:
        if frame.k == CONVERT_AT:
            # Order 0 (q a random walk): a full-rank transition noise, which the graph takes unfloored.
            founder = ArticulatedBlock(get_model("prismatic"), DRAWER, 0, 0.02, 0.05)
            q = float(AXIS @ (state.block_mean(4) - DRAWER.p0))
            state.replace_block(4, founder, np.array([q]), AXIS[None, :], np.array([[0.01**2]]))
        return set()

    def add_landmark(self, state, landmark_id, z_robot, R) -> None:
        if landmark_id == 5:
            founder = state.block(4)
            state.add_member(5, 4, _member_block(founder, member_structure(joint_of("prismatic", DRAWER),
                                                                           HANDLE_AT_ZERO)))
        else:
            super().add_landmark(state, landmark_id, z_robot, R)

    def after_frame(self, state, frame) -> None:
        if self.leave and frame.k == LEAVE_AT:
            state.detach_member(5, StaticPointBlock())


def _policy(leave=True):
    return _BodyScript(lambda i: StaticPointBlock(0.0 if i % 2 else 0.002), None, leave)


def _both(settings, leave=True):
    inputs = _inputs()
    ekf_state = BodySlamState(inputs.initial_pose_xytheta, np.zeros((3, 3)), 1)
    ekf = run_slam(inputs, _policy(leave), 1, state=ekf_state)
    graph_state = GraphBodyState(inputs.initial_pose_xytheta, np.zeros((3, 3)), 1, settings)
    graph = run_slam(inputs, _policy(leave), 1, state=graph_state)
    return ekf_state, ekf, graph_state, graph


# iSAM2 relinearises a variable once its update exceeds the threshold; on a linear problem that
# should change nothing, and with it off the comparison is of the factors' algebra alone.
NO_RELINEARISATION = Isam2Settings(floor_sigma=1e-7, relinearize_threshold=1e9)


def test_a_body_in_the_graph_is_the_ekfs_body_on_a_linear_gaussian_problem():
    ekf_state, ekf, graph_state, graph = _both(NO_RELINEARISATION)
    # Equal causal estimates over the conversion, the join, the member's updates and its leaving.
    np.testing.assert_allclose(graph.poses_xytheta, ekf.poses_xytheta, atol=1e-9, rtol=0)
    np.testing.assert_allclose(graph.pose_covs, ekf.pose_covs, atol=1e-9, rtol=0)
    for i in (4, 5):
        np.testing.assert_allclose(graph_state.block_mean(i), ekf_state.block_mean(i), atol=1e-9, rtol=0)
    assert isinstance(graph_state.block(5), StaticPointBlock) and graph_state.founder_of(5) is None


# Relinearising at every update, and iSAM2's default (relinearise where a variable moved by more than the
# threshold, every 10th update).
RELINEARISATION = {"always": dict(relinearize_skip=1, relinearize_threshold=1e-9), "default": {}}


@pytest.mark.parametrize("relinearisation", sorted(RELINEARISATION))
def test_relinearisation_leaves_a_linear_problem_with_an_articulated_block_unchanged(relinearisation):
    # Linear with the structure fixed only: a structure variable δ tilts the line, f = P0′ + q (n̂ + u e₁ + v e₂),
    # a product of q and δ (graph.structure), and the graph then estimates a model the EKF does not hold.
    settings = Isam2Settings(floor_sigma=1e-7, structure="fixed", **RELINEARISATION[relinearisation])
    _, ekf, _, graph = _both(settings, leave=False)
    np.testing.assert_allclose(graph.poses_xytheta, ekf.poses_xytheta, atol=1e-9, rtol=0)
    np.testing.assert_allclose(graph.pose_covs, ekf.pose_covs, atol=1e-9, rtol=0)


def test_relinearising_a_structure_variable_at_every_update_ends_at_the_batch_optimum():
    import gtsam

    settings = Isam2Settings(floor_sigma=1e-7, regate_probability=None, **RELINEARISATION["always"])
    *_, state, _ = _both(settings, leave=False)
    isam = state._solver._isam
    graph, estimate = isam.getFactorsUnsafe(), isam.calculateEstimate()
    optimum = gtsam.LevenbergMarquardtOptimizer(graph, estimate).optimize()
    # One Gauss-Newton step per update on the product of q and a barely observed tilt: the steps must not run away.
    assert graph.error(estimate) <= 1.01 * graph.error(optimum)


def test_a_member_reads_its_founders_variable_and_shares_its_marginal():
    *_, state, _ = _both(NO_RELINEARISATION, leave=False)
    assert state.founder_of(5) == 4 and state.members_of(4) == [5] and set(state.landmark_ids) >= {4, 5}
    assert state.founder_ids() == [0, 1, 2, 4]
    q = state.block_q(4)
    np.testing.assert_allclose(state.block_mean(5), state.block_mean(4), atol=0)
    np.testing.assert_allclose(state.landmark_position(5)[0], HANDLE_AT_ZERO + q * AXIS, atol=1e-12)
    for i in (4, 5):  # the scene recorder's position without the marginal: the same point
        np.testing.assert_array_equal(state.landmark_point(i), state.landmark_position(i)[0])
    # The trial EKF state of founder and member: one variable, its rows repeated, fully correlated.
    local = state._local([4, 5])
    a, b = local.indices(4), local.indices(5)
    np.testing.assert_allclose(local.P[np.ix_(a, a)], local.P[np.ix_(b, b)], atol=0)
    np.testing.assert_allclose(local.P[np.ix_(a, b)], local.P[np.ix_(a, a)], atol=0)
    with pytest.raises(ValueError, match="add_member"):
        state.add_member(6, 5, state.block(5))  # a member cannot found a body
