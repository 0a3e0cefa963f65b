"""SLAM inputs (one driver for simulated and RGB-D runs), per-observation R, and A-SLAM's generalised settings."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.config.robot import sensor_from_config
from stslam.config.sim import world_from_config
from stslam.config.slam import a_slam_from_config, filter_params_from_config
from stslam.sim.simulate import simulate
from stslam.slam.a_slam import run_a_slam
from stslam.slam.blocks import ArticulatedBlock, StaticPointBlock
from stslam.slam.core import SlamState
from stslam.slam.filters import make_filter, run_filter
from stslam.slam.inputs import SlamInputs, inputs_from_run

from conftest import compose_config


def _run(*overrides, seed=3):
    cfg = compose_config("dynamic_slam", ["world.n_frames=60", *overrides])
    world = world_from_config(cfg)
    return cfg, world, simulate(world, sensor_from_config(cfg), np.random.default_rng(seed))


def test_inputs_from_run_carry_the_run():
    _, world, run = _run()
    inputs = inputs_from_run(run)
    assert inputs.n_frames == world.n_frames
    np.testing.assert_array_equal(inputs.controls_vw, run.controls_odometry)
    np.testing.assert_array_equal(inputs.control_covs[5], run.control_cov(5))
    np.testing.assert_array_equal(inputs.dts_s, np.full(world.n_frames - 1, world.dt))
    np.testing.assert_array_equal(inputs.times_s, world.dt * np.arange(world.n_frames))
    k = int(np.argmax([ids.size for ids in run.observation_ids]))
    assert inputs.observation_covs[k].shape == (run.observation_ids[k].size, 3, 3)
    np.testing.assert_array_equal(inputs.observation_covs[k][-1], run.sensor.R)


def test_run_filter_takes_inputs_or_a_run_alike():
    cfg, world, run = _run()
    spec = make_filter("ekf_slam_gated", filter_params_from_config(cfg, "ekf_slam_gated"), world)
    a, b = run_filter(spec, run), run_filter(spec, inputs_from_run(run))
    np.testing.assert_array_equal(a.poses_xytheta, b.poses_xytheta)  # the same arithmetic: exactly equal


def test_inputs_reject_mismatched_lengths():
    _, _, run = _run()
    inputs = inputs_from_run(run)
    with pytest.raises(ValueError, match="controls"):
        SlamInputs(inputs.initial_pose_xytheta, inputs.controls_vw[:-1], inputs.control_covs, inputs.dts_s,
                   inputs.observation_ids, inputs.observations, inputs.observation_covs)
    with pytest.raises(ValueError, match="as many observation arrays"):
        SlamInputs(inputs.initial_pose_xytheta, inputs.controls_vw, inputs.control_covs, inputs.dts_s,
                   inputs.observation_ids, inputs.observations[:-1], inputs.observation_covs)


def _state_with_three_points():
    state = SlamState(np.array([0.2, -0.1, 0.3]), 0.01 * np.eye(3))
    R = 0.04**2 * np.eye(3)
    for i, z in enumerate(([2.0, 0.5, 0.1], [1.5, -1.0, 0.3], [3.0, 1.2, -0.2])):
        state.add_landmark(i, StaticPointBlock(0.0), np.array(z), R)
    return state, R


def test_per_observation_R_is_used_per_observation():
    zs = np.array([[2.05, 0.48, 0.12], [1.47, -1.03, 0.31], [2.96, 1.25, -0.18]])
    one, R = _state_with_three_points()
    many, _ = _state_with_three_points()
    one.update_landmarks([0, 1, 2], zs, R)
    many.update_landmarks([0, 1, 2], zs, np.broadcast_to(R, (3, 3, 3)))
    np.testing.assert_array_equal(one.x, many.x)  # one R for all = the same R for each, exactly
    # An observation with a practically infinite R (1e12 m²) adds nothing: the update equals the one
    # without it up to the Kalman gain left for it, ~P/R ≈ 1e-14 relative, so 1e-10 is a safe bound.
    dropped, _ = _state_with_three_points()
    dropped.update_landmarks([0, 2], zs[[0, 2]], R)
    huge, _ = _state_with_three_points()
    huge.update_landmarks([0, 1, 2], zs, np.stack([R, 1e12 * np.eye(3), R]))
    np.testing.assert_allclose(huge.x, dropped.x, atol=1e-10)
    np.testing.assert_allclose(huge.P, dropped.P, atol=1e-10)


def test_convert_and_classify_every_limit_what_a_slam_does():
    cfg, world, run = _run("+filters.a_slam.convert=[revolute]", "+filters.a_slam.classify_every=2",
                           "world.n_frames=120")
    models = set()

    def observer(k, state):
        for i in state.landmark_ids:
            block = state.block(i)
            if isinstance(block, ArticulatedBlock):
                models.add(block.model.name)

    track = run_a_slam(a_slam_from_config(cfg), run, observer=observer)
    assert models <= {"revolute"}  # a prismatic decision never gives a prismatic block
    sightings = {}
    for ids in run.observation_ids:
        for i in ids.tolist():
            sightings[i] = sightings.get(i, 0) + 1
    for i, report in track.landmarks.items():
        # Every 2nd sighting at most goes to the selector (the 1st, 3rd, …).
        assert report.mu_frames.size <= (sightings[i] + 1) // 2
    # Not vacuous: selection did decide prismatic for some landmark (recorded only) and revolute for another.
    decided = {model for report in track.landmarks.values() for _, _, model in report.decisions}
    assert {"prismatic", "revolute"} <= decided
