"""A-SLAM told the truth about motion (``run_a_slam``'s ``moving``; the method ``a_slam_truth_onsets``): the bound a
perfect onset test sets (issue 38, SPEC 18). The hook must change nothing when it knows of no motion, and hold
out every observation of a point held static when it knows of all of them."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.config.robot import sensor_from_config
from stslam.config.sim import world_from_config
from stslam.config.slam import a_slam_from_config, filter_params_from_config
from stslam.sim.simulate import simulate
from stslam.slam.a_slam import run_a_slam
from stslam.slam.blocks import StaticPointBlock
from stslam.slam.decision_scores import truly_moving
from stslam.slam.filters import make_filter, run_filter
from stslam.slam.inputs import as_inputs
from stslam.slam.loop import BlockPolicy, run_slam

from conftest import compose_config


def _setup():
    cfg = compose_config("dynamic_slam", [])
    world = world_from_config(cfg)
    return a_slam_from_config(cfg), world, simulate(world, sensor_from_config(cfg), np.random.default_rng(3))


def test_truly_moving_marks_the_movers_frames_from_the_true_positions():
    _, world, _ = _setup()
    moving = truly_moving(world)
    assert moving.shape == (world.n_frames, world.n_landmarks)
    assert not moving[0].any()  # nothing is known to move at the first frame
    static = [i for i, truth in enumerate(world.landmarks) if truth.model_name == "static"]
    assert static and not moving[:, static].any()
    drawer, door = 40, 41  # the default world's movers: each moves at every frame
    assert moving[1:, drawer].all() and moving[1:, door].all()


def test_a_motion_truth_of_the_wrong_shape_is_refused():
    params, world, run = _setup()
    with pytest.raises(ValueError, match=r"moving: expected a bool array \(n_frames ≥ \d+, n_landmarks\), got bool"):
        run_a_slam(params, run, moving=np.zeros((3, world.n_landmarks), dtype=bool))
    with pytest.raises(ValueError, match="got float64"):
        run_a_slam(params, run, moving=np.zeros((world.n_frames, world.n_landmarks)))


def test_no_known_motion_changes_nothing():
    params, world, run = _setup()
    plain = run_a_slam(params, run)
    told = run_a_slam(params, run, moving=np.zeros((world.n_frames, world.n_landmarks), dtype=bool))
    # The same arithmetic in the same order: equal to the bit.
    np.testing.assert_array_equal(plain.poses_xytheta, told.poses_xytheta)
    np.testing.assert_array_equal(plain.pose_covs, told.pose_covs)


def test_points_known_to_move_never_update_the_robot():
    # With no decisions (selection never fed: no pose is that certain) every landmark stays a static
    # point; told that all of them move at every frame, A-SLAM holds out every observation and its
    # robot is dead reckoning: the shared core's predictions with every observation gated away.
    cfg = compose_config("dynamic_slam", ["filters.a_slam.max_pose_sigma_m=1e-9"])
    world = world_from_config(cfg)
    run = simulate(world, sensor_from_config(cfg), np.random.default_rng(3))
    params = a_slam_from_config(cfg)
    told = run_a_slam(params, run, moving=np.ones((world.n_frames, world.n_landmarks), dtype=bool))
    dead_reckoning = run_slam(as_inputs(run), BlockPolicy(lambda i: StaticPointBlock(0.0), max_nis=-1.0))
    np.testing.assert_allclose(told.poses_xytheta, dead_reckoning.poses_xytheta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(told.pose_covs, dead_reckoning.pose_covs, rtol=0, atol=1e-15)
    # Not so without the truth: the static points correct the robot (the test above can fail).
    plain = run_a_slam(params, run)
    assert np.abs(plain.poses_xytheta - dead_reckoning.poses_xytheta).max() > 0.05


def test_the_truth_onsets_method_is_a_slam_told_the_truth():
    # ``methods=[..., a_slam_truth_onsets]``: A-SLAM's own settings (filters.a_slam) with the world's motion truth.
    cfg = compose_config("dynamic_slam", [])
    world = world_from_config(cfg)
    run = simulate(world, sensor_from_config(cfg), np.random.default_rng(3))
    params = filter_params_from_config(cfg, "a_slam_truth_onsets")
    assert params == filter_params_from_config(cfg, "a_slam")
    method = run_filter(make_filter("a_slam_truth_onsets", params, world), run)
    told = run_a_slam(params, run, moving=truly_moving(world))
    np.testing.assert_array_equal(method.poses_xytheta, told.poses_xytheta)
    plain = run_a_slam(params, run)
    assert not np.array_equal(method.poses_xytheta, plain.poses_xytheta)  # the truth held something out
