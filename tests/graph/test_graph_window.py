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


def _sliding_point_run(settings, wrong_first: bool, refits=(8,), updates=None, restart_at=None, walk=0.0):
    """A robot on a straight line sees one point sliding along x; noise-free odometry and observations.

    The point is a static point for 6 frames, then converted to a prismatic block (on a line 5 cm off
    when ``wrong_first``, refitted onto the true line at each frame of ``refits``: a new block object each
    time). ``updates``, a list: the frame of each iSAM2 update is appended to it. ``restart_at``: at that
    frame (< 6) the static point is restarted (its gate rejects the observation, and it is put back as a
    new static point from it, as A-SLAM does after ``restart_after`` rejections). ``walk``: the static
    point's random walk.
    """
    true_line = PrismaticStructure(np.array([0.0, 2.0, 0.3]), np.array([1.0, 0.0, 0.0]), 0.0)
    off_line = PrismaticStructure(np.array([0.0, 2.05, 0.3]), np.array([1.0, 0.0, 0.0]), 0.0)
    model = get_model("prismatic")
    u, S, R = np.array([0.3, 0.0]), np.diag([0.02**2, 0.01**2]), 0.02**2 * np.eye(3)
    pose = np.zeros(3)
    state = GraphState(pose, np.zeros((3, 3)), motion_order=1, settings=settings)
    if updates is not None:
        solver_update = state._solver.update
        state._solver.update = lambda *args, **kwargs: updates.append(state.k) or solver_update(*args, **kwargs)
    poses = [pose]
    for k in range(14):
        if k:
            pose = move(pose, u, 1.0)
            poses.append(pose)
            state.predict(u, S, 1.0)
        z = observe(pose, model.position(true_line, np.array([0.1 * k])))
        if k == 0:
            state.add_landmark(0, StaticPointBlock(walk), z, R)
        elif k == restart_at:
            assert not state.update_landmarks([0], z.reshape(1, 3), R, max_nis=0.0)[0][0]
            state.remove_landmark(0)
            state.add_landmark(0, StaticPointBlock(walk), z, R)
        elif k == 6:
            state.remove_landmark(0)
            block = ArticulatedBlock(model, off_line if wrong_first else true_line, 1, 1e-3, 100.0)
            state.add_landmark(0, block, z, R)
        else:
            state.update_landmarks([0], z.reshape(1, 3), R)
        if k in refits and wrong_first:
            x = state.block_mean(0)
            state.replace_block(0, ArticulatedBlock(model, true_line, 1, 1e-3, 100.0), x, np.eye(2), np.zeros((2, 2)))
        state.pose
    return np.array(poses), state.smoothed()[0]


def test_rereading_the_static_past_as_the_joint_removes_its_pull():
    truth, plain = _sliding_point_run(Isam2Settings(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1), wrong_first=False)
    _, reread = _sliding_point_run(Isam2Settings(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1, reread=True), wrong_first=False)
    assert np.abs(plain - truth).max() > 1e-3  # the sliding point, read as static, bends the past
    np.testing.assert_allclose(reread, truth, atol=1e-6)


def test_a_conversion_rereads_the_static_chains_its_restarts_ended():
    # Restarted at frame 3, the point's first static chain (frames 0-2) stays a fixed point's unless the
    # conversion at frame 6 re-reads it with the second chain (reread_restarts).
    base = dict(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1, reread=True)
    truth, kept = _sliding_point_run(Isam2Settings(**base), wrong_first=False, restart_at=3)
    _, reread = _sliding_point_run(Isam2Settings(**base, reread_restarts=True), wrong_first=False, restart_at=3)
    assert np.abs(kept - truth).max() > 1e-3  # frames 0-2 read as a static point bend the past
    np.testing.assert_allclose(reread, truth, atol=1e-6)


def test_a_walking_static_past_is_not_reread():
    # A walking point's chain has a variable per frame tied by its walk; the re-read (which takes one
    # variable's factors apart) leaves it as it is: the same smoothing as without re-reading (a kitchen seed
    # once stopped in gtsam, a key missing, when the re-read met such a chain).
    base = dict(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1)
    _, plain = _sliding_point_run(Isam2Settings(**base), wrong_first=False, restart_at=3, walk=1e-4)
    _, asked = _sliding_point_run(Isam2Settings(**base, reread=True, reread_restarts=True), wrong_first=False,
                                  restart_at=3, walk=1e-4)
    np.testing.assert_allclose(asked, plain, atol=1e-9)


def test_a_refit_rereads_every_observation_on_the_new_structure():
    truth, kept = _sliding_point_run(Isam2Settings(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1, reread=True, structure="fixed", reread_refits=False), True)
    _, refit = _sliding_point_run(Isam2Settings(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1, reread=True, structure="fixed", reread_refits=True), True)
    assert np.abs(kept - truth).max() > 1e-3  # frames 6-8 stay on the line 5 cm off
    np.testing.assert_allclose(refit, truth, atol=1e-6)


@pytest.mark.parametrize("every", [1, 3, 100])
def test_refit_rereads_on_a_schedule_end_at_the_latest_variable(every):
    # Refits at frames 8, 9 and 10: the first is re-read at frame 9, the others wait ``every`` frames from
    # it (100: until the end); a waiting re-read ends at the landmark's latest variable, which has been
    # carried on from the refit's own one, so each observation still enters once, on the true line.
    settings = Isam2Settings(floor_sigma=1e-6, relinearize_threshold=1e-8, relinearize_skip=1, reread=True,
                             structure="fixed", reread_refit_frames=every)
    updates: list = []
    truth, refit = _sliding_point_run(settings, True, refits=(8, 9, 10), updates=updates)
    np.testing.assert_allclose(refit, truth, atol=1e-6)
    assert updates[:14] == list(range(14))  # one iSAM2 update per frame, re-read frames included
    with pytest.raises(ValueError, match="reread_refit_frames must be an integer ≥ 1"):
        Isam2Settings(reread_refit_frames=0)


def test_a_refit_with_no_past_to_reread_keeps_its_buffered_conversion():
    # Refitted at its first frame, after that frame's update: the refit's factor waits in the buffer, and at
    # the next frame there is no earlier observation to re-read, so the refit stays as it is (its variable
    # tied to the old one; a re-read that took the factor out anyway left the variable undetermined).
    model = get_model("prismatic")
    line = PrismaticStructure(np.array([0.0, 2.0, 0.3]), np.array([1.0, 0.0, 0.0]), 0.0)
    u, S, R = np.array([0.3, 0.0]), np.diag([0.02**2, 0.01**2]), 0.02**2 * np.eye(3)
    state = GraphState(np.zeros(3), np.zeros((3, 3)), motion_order=1,
                       settings=Isam2Settings(floor_sigma=1e-6, structure="variable", reread_refits=True))
    pose = np.zeros(3)
    for k in range(4):
        if k:
            pose = move(pose, u, 1.0)
            state.predict(u, S, 1.0)
        z = observe(pose, model.position(line, np.array([0.1 * k])))
        if k == 0:
            state.add_landmark(0, ArticulatedBlock(model, line, 1, 1e-3, 100.0), z, R)
            state.pose
            x, first = state.block_mean(0), state._heads[0][0]
            state.replace_block(0, ArticulatedBlock(model, line, 1, 1e-3, 100.0), x, np.eye(2), np.zeros((2, 2)))
            refit = state._heads[0][0]
        else:
            state.update_landmarks([0], z.reshape(1, 3), R)
        state.pose
    held = state._solver._isam.getFactorsUnsafe()
    assert any(held.at(i) is not None and set(held.at(i).keys()) == {first, refit} for i in range(held.size()))
    assert np.all(np.isfinite(state.smoothed()[0]))
