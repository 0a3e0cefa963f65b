"""World definitions (SPEC 8.4) and the simulation of one run (SPEC 5)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.robot.motion import move
from stslam.config.robot import sensor_from_config
from stslam.config.sim import world_from_config
from stslam.errors import ConfigError
from stslam.sim.simulate import simulate
from stslam.sim.worlds import keyframe_profile

from conftest import compose_config

# Worlds are written with full-precision floats for fractions (1/3 = 0.3333333333333333),
# so positions agree with the fractions to a few ulps of numbers ≤ 10: 1e-12.
EXACT = 1e-12


@pytest.fixture(scope="module")
def paper_square():
    return world_from_config(compose_config("dynamic_slam", ["world=paper_square"]))


@pytest.fixture(scope="module")
def square_centred():
    return world_from_config(compose_config("dynamic_slam", []))


def test_paper_square_static_landmarks_match_spec(paper_square):
    static = [lm for lm in paper_square.landmarks if lm.model_name == "static"]
    assert len(static) == 40 and paper_square.n_landmarks == 42
    p = np.array([lm.structure.p0 for lm in static])
    low, high = 1 / 3, 19 / 3
    on_edge = (np.isclose(p[:, 0], low) | np.isclose(p[:, 0], high) | np.isclose(p[:, 1], low)
               | np.isclose(p[:, 1], high))
    assert on_edge.all()
    assert np.all((p[:, :2] >= low - EXACT) & (p[:, :2] <= high + EXACT))
    # Neighbours along each side are 2/3 m apart; heights run (i + 1)/30, i = 0…9.
    for side in range(4):
        block = p[10 * side:10 * side + 10]
        np.testing.assert_allclose(np.linalg.norm(np.diff(block[:, :2], axis=0), axis=1), 2 / 3, atol=EXACT)
        np.testing.assert_allclose(block[:, 2], (np.arange(10) + 1) / 30, atol=EXACT)
    # Static landmarks never move.
    np.testing.assert_array_equal(np.ptp(paper_square.positions[:, :40], axis=0), 0.0)


def test_paper_square_moving_landmarks_match_spec(paper_square):
    names = [lm.name for lm in paper_square.landmarks]
    prismatic = paper_square.positions[:, names.index("prismatic")]
    k = np.arange(paper_square.n_frames)
    np.testing.assert_allclose(prismatic, np.column_stack([4 / 3 + k / 30, np.full_like(k, 16 / 3, dtype=float),
                                                           np.zeros(k.size)]), atol=EXACT)
    revolute = paper_square.positions[:, names.index("revolute")]
    offset = revolute[:, :2] - 13 / 3
    np.testing.assert_allclose(np.linalg.norm(offset, axis=1), np.sqrt(200) / 30, atol=EXACT)
    turn = np.diff(np.unwrap(np.arctan2(offset[:, 1], offset[:, 0])))
    np.testing.assert_allclose(turn, np.pi / 5, atol=1e-12)
    np.testing.assert_allclose(revolute[0], [4.0, 4.0, 0.0], atol=EXACT)  # our start angle 5π/4


def test_paper_square_robot_path_matches_spec(paper_square):
    k = np.arange(110)
    poses = paper_square.poses_xytheta
    assert poses.shape == (110, 3)
    np.testing.assert_allclose(poses[:, 0], 4 / 3 + 10 / 3 * np.cos(k * np.pi / 50), atol=EXACT)
    np.testing.assert_allclose(poses[:, 1], 4 / 3 + 10 / 3 * np.sin(k * np.pi / 50), atol=EXACT)
    np.testing.assert_allclose(poses[:, 2], np.pi / 2 + k * np.pi / 50, atol=EXACT)
    np.testing.assert_allclose(paper_square.alpha, [0.1, 0.05, 0.05, 0.1])
    assert paper_square.dt == 1.0


def test_square_centred_shares_landmarks_but_not_the_robot_circle(paper_square, square_centred):
    np.testing.assert_array_equal(square_centred.positions, paper_square.positions)
    centre = square_centred.poses_xytheta[:, :2] - 10 / 3
    np.testing.assert_allclose(np.linalg.norm(centre, axis=1), 2.0, atol=EXACT)
    assert square_centred.n_frames == 110


def test_true_controls_reproduce_the_path(square_centred):
    # The simulated path lies on SPEC 5.1 arcs: driving the model with the recovered true
    # controls from the true start retraces it (round-off only, ~1e-13 over 110 steps).
    cfg = compose_config("dynamic_slam", ["robot.control_noise=false"])
    run = simulate(square_centred, sensor_from_config(cfg), np.random.default_rng(0), control_noise=False)
    pose = square_centred.poses_xytheta[0]
    for k, u in enumerate(run.controls_odometry, start=1):
        pose = move(pose, u, square_centred.dt)
        np.testing.assert_allclose(pose, square_centred.poses_xytheta[k], atol=1e-10)
    np.testing.assert_allclose(run.controls_true[:, 0], 2 * np.pi / 50, atol=1e-12)  # v = rΔa, r = 2
    np.testing.assert_allclose(run.controls_true[:, 1], np.pi / 50, atol=1e-12)


def test_visibility_statistics_match_the_spec_description(paper_square, square_centred):
    # SPEC 8.4: in paper_square with the cone about 45 of 110 frames see nothing and ~2.9 static
    # landmarks are visible per frame; square_centred sees ~7 static per frame and no blind frame.
    cfg = compose_config("dynamic_slam", [])
    sensor = sensor_from_config(cfg)
    paper_run = simulate(paper_square, sensor, np.random.default_rng(0))
    blind = sum(ids.size == 0 for ids in paper_run.observation_ids)
    static_per_frame = np.mean([np.count_nonzero(ids < 40) for ids in paper_run.observation_ids])
    assert 40 <= blind <= 50
    assert 2.5 <= static_per_frame <= 3.3
    centred_run = simulate(square_centred, sensor, np.random.default_rng(0))
    assert min(ids.size for ids in centred_run.observation_ids) > 0
    assert 6.0 <= np.mean([np.count_nonzero(ids < 40) for ids in centred_run.observation_ids]) <= 8.5


def test_simulation_is_deterministic_and_noise_has_the_configured_sigma(square_centred):
    cfg = compose_config("dynamic_slam", [])
    sensor = sensor_from_config(cfg)
    a = simulate(square_centred, sensor, np.random.default_rng(3))
    b = simulate(square_centred, sensor, np.random.default_rng(3))
    for za, zb in zip(a.observations, b.observations):
        np.testing.assert_array_equal(za, zb)
    np.testing.assert_array_equal(a.controls_odometry, b.controls_odometry)
    from stslam.robot.sensor import observe
    residuals = np.vstack([z - observe(square_centred.poses_xytheta[k], square_centred.positions[k, ids])
                           for k, (ids, z) in enumerate(zip(a.observation_ids, a.observations))])
    # ~2700 values: the sample std of N(0, σ²) has relative SE 1/√(2·2700) ≈ 1.4%; 6% is 4 SE.
    assert residuals.std() == pytest.approx(0.04, rel=0.06)


def test_kitchen_points_has_the_spec_ingredients():
    world = world_from_config(compose_config("dynamic_slam", ["world=kitchen_points"]))
    models = [lm.model_name for lm in world.landmarks]
    assert models.count("static") == 10 and world.n_frames == 330
    moving = [lm for lm in world.landmarks if lm.model_name != "static"]
    assert len(moving) == 7 and all(lm.body is None for lm in world.landmarks) and {"revolute", "prismatic"} <= {lm.model_name for lm in moving}
    np.testing.assert_allclose(world.alpha, np.array([0.1, 0.05, 0.05, 0.1]) / 10)
    # A dishwasher door: a revolute joint with a horizontal axis.
    axes = [lm.structure.normal for lm in moving if lm.model_name == "revolute"]
    assert any(abs(a[2]) < 1e-12 for a in axes) and any(abs(abs(a[2]) - 1) < 1e-12 for a in axes)
    # Each moves, pauses and moves back: q returns to 0 after leaving it, several times.
    for lm in moving:
        q = lm.q[:, 0]
        leaves = np.count_nonzero((q[:-1] == 0) & (q[1:] > 0))
        assert leaves >= 2 and q[-1] == 0.0 and np.count_nonzero(np.diff(q) == 0) > 100
    # The doors' radii differ (varied structures).
    assert len({round(lm.structure.radius, 3) for lm in moving if lm.model_name == "revolute"}) >= 3


def test_keyframe_profile_eases_between_keyframes():
    q = keyframe_profile([(2, 0.0), (6, 1.0), (8, 1.0)], 10)
    np.testing.assert_allclose(q[:3], 0.0)
    assert q[4] == pytest.approx(0.5)  # half-way: (1 − cos(π/2))/2
    np.testing.assert_allclose(q[6:], 1.0)


def test_kitchen_parts_carry_several_points_that_move_rigidly():
    world = world_from_config(compose_config("dynamic_slam", ["world=kitchen"]))
    single = world_from_config(compose_config("dynamic_slam", ["world=kitchen_points"]))
    assert world.name == "kitchen" and world.n_frames == single.n_frames
    np.testing.assert_array_equal(world.poses_xytheta, single.poses_xytheta)
    assert sum(lm.model_name == "static" for lm in world.landmarks) == 10
    parts = {}
    for i, lm in enumerate(world.landmarks):
        if lm.body is not None:
            parts.setdefault(lm.body, []).append(i)
    one = {lm.name: lm for lm in single.landmarks if lm.model_name != "static"}
    assert set(parts) == set(one)
    for name, members in parts.items():
        assert 3 <= len(members) <= 6
        truth = one[name]
        for i in members:  # every point has its part's model and motion
            assert world.landmarks[i].model_name == truth.model_name
            np.testing.assert_array_equal(world.landmarks[i].q, truth.q)
        # Rigid: distances between the part's points are the same in every frame.
        p = world.positions[:, members]
        d = np.linalg.norm(p[:, :, None] - p[:, None, :], axis=-1)
        np.testing.assert_allclose(d, np.broadcast_to(d[0], d.shape), atol=1e-12)
        moved = np.linalg.norm(p - p[0], axis=-1).max()
        assert moved > 0.2
    # The one-point world's door point is one of the part's points: same trajectory.
    door = [i for i in parts["fridge_door"] if np.allclose(world.positions[0, i], single.positions[0, 10])][0]
    np.testing.assert_allclose(world.positions[:, door], single.positions[:, 10], atol=1e-12)


def test_part_points_need_to_be_off_the_hinge_axis():
    cfg = compose_config("dynamic_slam", ["world=kitchen"])
    cfg["world"]["landmarks"][0]["points"][1] = [0.4, 5.0, 0.7]  # on the fridge hinge
    with pytest.raises(ConfigError, match=r"world.landmarks\[0\].points\[1\]: expected a point off the hinge axis"):
        world_from_config(cfg)
