"""The fixed-lag solver and the re-reading of a landmark's past under a new model (SPEC 14)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gtsam")

from stslam.articulation.models import PrismaticStructure, get_model  # noqa: E402
from stslam.graph.run import run_filter_isam2  # noqa: E402
from stslam.graph.state import GraphState, Isam2Settings  # noqa: E402
from stslam.robot.motion import move  # noqa: E402
from stslam.robot.sensor import observe  # noqa: E402
from stslam.slam.blocks import ArticulatedBlock, StaticPointBlock  # noqa: E402
from stslam.slam.filters import FilterSpec  # noqa: E402
from stslam.slam.loop import BlockPolicy, run_slam  # noqa: E402

from test_graph_state import _block, _linear_inputs  # noqa: E402


def test_a_window_on_a_linear_gaussian_problem_keeps_the_causal_estimate_exact():
    # Marginalising a linear-Gaussian graph is exact: over a window the causal estimate is still the EKF's.
    inputs = _linear_inputs()
    spec = FilterSpec("mixed", lambda _: BlockPolicy(_block), motion_order=1)
    ekf = run_slam(inputs, spec.policy_for(inputs), motion_order=1)
    windowed = Isam2Settings(floor_sigma=1e-7, lag_s=3.0, windowed=("mixed",))
    graph = run_filter_isam2(spec, inputs, windowed)
    np.testing.assert_allclose(graph.online_poses_xytheta, ekf.poses_xytheta, atol=1e-9, rtol=0)
    np.testing.assert_allclose(graph.online_pose_covs, ekf.pose_covs, atol=1e-9, rtol=0)
    full = run_filter_isam2(spec, inputs, Isam2Settings(floor_sigma=1e-7))
    np.testing.assert_allclose(graph.poses_xytheta[-1], full.poses_xytheta[-1], atol=1e-9, rtol=0)
    # Poses that left the window keep their fixed-lag estimate, which differs from the full smoother's.
    assert np.abs(graph.poses_xytheta[:5] - full.poses_xytheta[:5]).max() > 1e-7


def test_a_method_not_in_windowed_runs_on_the_full_smoother():
    inputs = _linear_inputs()
    spec = FilterSpec("mixed", lambda _: BlockPolicy(_block), motion_order=1)
    full = run_filter_isam2(spec, inputs, Isam2Settings(floor_sigma=1e-7))
    other = run_filter_isam2(spec, inputs, Isam2Settings(floor_sigma=1e-7, lag_s=3.0, windowed=("dyn_slam",)))
    np.testing.assert_array_equal(other.poses_xytheta, full.poses_xytheta)


def _sliding_point_run(settings, wrong_first: bool):
    """A robot on a straight line sees one point sliding along x; noise-free odometry and observations.

    The point is a static point for 6 frames, then converted to a prismatic block (on a line 5 cm off
    when ``wrong_first``, refitted onto the true line two frames later).
    """
    true_line = PrismaticStructure(np.array([0.0, 2.0, 0.3]), np.array([1.0, 0.0, 0.0]), 0.0)
    off_line = PrismaticStructure(np.array([0.0, 2.05, 0.3]), np.array([1.0, 0.0, 0.0]), 0.0)
    model = get_model("prismatic")
    u, S, R = np.array([0.3, 0.0]), np.diag([0.02**2, 0.01**2]), 0.02**2 * np.eye(3)
    pose = np.zeros(3)
    state = GraphState(pose, np.zeros((3, 3)), motion_order=1, settings=settings)
    poses = [pose]
    for k in range(14):
        if k:
            pose = move(pose, u, 1.0)
            poses.append(pose)
            state.predict(u, S, 1.0)
        z = observe(pose, model.position(true_line, np.array([0.1 * k])))
        if k == 0:
            state.add_landmark(0, StaticPointBlock(), z, R)
        elif k == 6:
            state.remove_landmark(0)
            block = ArticulatedBlock(model, off_line if wrong_first else true_line, 1, 1e-3, 100.0)
            state.add_landmark(0, block, z, R)
        else:
            state.update_landmarks([0], z.reshape(1, 3), R)
        if k == 8 and wrong_first:
            x = state.block_mean(0)
            state.replace_block(0, ArticulatedBlock(model, true_line, 1, 1e-3, 100.0), x, np.eye(2), np.zeros((2, 2)))
        state.pose
    return np.array(poses), state.smoothed()[0]


def test_rereading_the_static_past_as_the_joint_removes_its_pull():
    truth, plain = _sliding_point_run(Isam2Settings(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1), wrong_first=False)
    _, reread = _sliding_point_run(Isam2Settings(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1, reread=True), wrong_first=False)
    assert np.abs(plain - truth).max() > 1e-3  # the sliding point, read as static, bends the past
    np.testing.assert_allclose(reread, truth, atol=1e-6)


def test_a_refit_rereads_every_observation_on_the_new_structure():
    truth, kept = _sliding_point_run(Isam2Settings(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1, reread=True, structure="fixed", reread_refits=False), True)
    _, refit = _sliding_point_run(Isam2Settings(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1, reread=True, structure="fixed", reread_refits=True), True)
    assert np.abs(kept - truth).max() > 1e-3  # frames 6-8 stay on the line 5 cm off
    np.testing.assert_allclose(refit, truth, atol=1e-6)
