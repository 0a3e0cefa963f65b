"""A block with a slip (stslam.slam.blocks) in the iSAM2 state: the EKF's estimate on a linear-Gaussian problem."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

pytest.importorskip("gtsam")

from stslam.articulation.models import PrismaticStructure, get_model  # noqa: E402
from stslam.graph.state import GraphState, Isam2Settings  # noqa: E402
from stslam.slam.blocks import ArticulatedBlock, StaticPointBlock  # noqa: E402
from stslam.slam.core import SlamState  # noqa: E402
from linear_scene import straight_line_inputs  # noqa: E402
from stslam.slam.loop import BlockPolicy, run_slam  # noqa: E402

AXIS = np.array([1.0, 0.0, 0.0])
DRAWER = PrismaticStructure(p0=np.array([1.5, 1.0, 0.4]), direction=AXIS, residual_m=0.0)
CONVERT_AT = 3


def _inputs(seed=0, n=14):
    """A prismatic block with a slip is linear in the state on a straight line (linear_scene). Points 0-2
    are static; point 4 moves along x by 0.02 m per frame and creeps along y by 3 mm per frame."""
    static = np.array([[1.0, 1.0, 0.2], [2.0, -1.0, 0.5], [1.5, 0.5, 0.0]])

    def world_at(k):
        mover = DRAWER.p0 + 0.02 * k * AXIS + np.array([0.0, 0.003 * max(k - CONVERT_AT, 0), 0.0])
        return [0, 1, 2, 4], np.vstack([static, mover])

    return straight_line_inputs(world_at, n, 0.03, seed)


@dataclass(frozen=True)
class _ConvertWithSlip(BlockPolicy):
    """Landmark 4 is converted at CONVERT_AT the way A-SLAM converts (its landmark policy): the static point
    is removed and the frame's observation starts a slipping prismatic block (slip 0 exactly at the start)."""

    def before_update(self, state, frame) -> set:
        if frame.k == CONVERT_AT:
            j = list(frame.ids).index(4)
            state.remove_landmark(4)
            block = ArticulatedBlock(get_model("prismatic"), DRAWER, 0, 0.02, 0.05, sigma_slip=0.01)
            state.add_landmark(4, block, frame.zs[j], frame.Rs[j])
            return {j}
        return set()


def test_a_slipping_block_in_the_graph_is_the_ekfs_on_a_linear_gaussian_problem():
    inputs = _inputs()
    policy = _ConvertWithSlip(lambda i: StaticPointBlock(0.0), None)
    ekf_state = SlamState(inputs.initial_pose_xytheta, np.zeros((3, 3)), 1)
    ekf = run_slam(inputs, policy, 1, state=ekf_state)
    # No relinearisation: the comparison is of the factors' algebra; the floor (1e-7) is far below 1e-9 in effect.
    graph_state = GraphState(inputs.initial_pose_xytheta, np.zeros((3, 3)), 1,
                             Isam2Settings(floor_sigma=1e-7, relinearize_threshold=1e9, structure="fixed"))
    graph = run_slam(inputs, policy, 1, state=graph_state)
    assert graph_state.block(4).size == 4  # q and a slip of 3: the conversion's observation fixes q alone
    np.testing.assert_allclose(graph.poses_xytheta, ekf.poses_xytheta, atol=1e-9, rtol=0)
    np.testing.assert_allclose(graph.pose_covs, ekf.pose_covs, atol=1e-9, rtol=0)
    np.testing.assert_allclose(graph_state.block_mean(4), ekf_state.block_mean(4), atol=1e-9, rtol=0)
    # The slip took up the creep along y, which no motion along the drawer can explain.
    assert graph_state.block_mean(4)[2] > 0.01
