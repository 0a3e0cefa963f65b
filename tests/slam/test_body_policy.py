"""Bodies in the SLAM state (SPEC 13): members alias their founder's motion state."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.slam.bodies.joint import BodyJoint, member_position, member_structure
from stslam.articulation.models import get_model
from stslam.robot.sensor import observe
from stslam.sim.worlds import revolute_structure
from stslam.slam.a_slam_settings import BodySettings
from stslam.slam.bodies.grouping import BodyGrouping, _member_block
from stslam.slam.bodies.state import BodySlamState
from stslam.slam.blocks import ArticulatedBlock, StaticPointBlock

from conftest import compose_config

HINGE = BodyJoint("revolute", np.array([2.0, 3.0, 1.0]), np.array([0.0, 0.0, 1.0]))


def _state_with_body():
    """Robot at the origin, a revolute founder (door edge) and one member (the handle), both at φ = 0.3."""
    state = BodySlamState(np.array([0.0, 0.0, 0.2]), 1e-4 * np.eye(3))
    founder = ArticulatedBlock(get_model("revolute"), revolute_structure(HINGE.point, HINGE.direction,
                                                                         [1.0, 0.0, 0.0], 0.8), 1, 0.01, 0.1)
    m = founder.model.position(founder.structure, np.array([0.3]))
    state.add_landmark(7, founder, observe(state.pose, m), 0.02 ** 2 * np.eye(3))
    handle = member_structure(HINGE, HINGE.point + np.array([0.7, 0.0, -0.2]))
    state.add_member(8, 7, _member_block(founder, handle))
    return state, founder


def test_a_member_reads_and_updates_its_founders_motion_state():
    state, founder = _state_with_body()
    assert 8 in state and state.founder_of(8) == 7 and state.members_of(7) == [8]
    assert set(state.landmark_ids) == {7, 8} and state.x.size == 3 + founder.size
    np.testing.assert_array_equal(state.indices(8), state.indices(7))
    phi = state.x[state.indices(7)][0]
    handle = state.landmark_position(8)[0]
    np.testing.assert_allclose(handle, member_position(HINGE, HINGE.point + [0.7, 0.0, -0.2], 0.0, phi), atol=1e-12)
    # H of a member's observation by numerical differences over the whole state.
    z_hat, cols, H = state.predict_observation(8)
    numeric = np.zeros((3, state.x.size))
    for c in range(state.x.size):
        dx = np.zeros(state.x.size)
        dx[c] = 1e-6
        numeric[:, c] = (state.predict_observation(8, state.x + dx)[0] - state.predict_observation(8, state.x - dx)[0]) / 2e-6
    np.testing.assert_allclose(numeric[:, cols], H, atol=1e-7)
    # The member's observation at a larger angle moves the founder's φ towards it.
    z = observe(state.pose, member_position(HINGE, HINGE.point + [0.7, 0.0, -0.2], 0.0, phi + 0.1))
    assert state.update_landmark(8, z, 0.01 ** 2 * np.eye(3)).accepted
    assert state.x[state.indices(7)][0] > phi + 0.05


def test_copy_and_detach_keep_the_body_apart():
    state, _ = _state_with_body()
    trial = state.copy()
    assert isinstance(trial, BodySlamState) and trial.founder_of(8) == 7
    trial.remove_member(8)
    assert 8 in state and 8 not in trial
    m, cov = state.landmark_position(8)
    cross_robot = state.P[:3, state.indices(8)] @ state.block(8).position(state.x[state.indices(8)])[1].T
    state.detach_member(8, StaticPointBlock(0.0))
    assert state.founder_of(8) is None and isinstance(state.block(8), StaticPointBlock)
    np.testing.assert_allclose(state.block_mean(8), m)
    np.testing.assert_allclose(state.P[np.ix_(state.indices(8), state.indices(8))], cov, atol=1e-15)
    np.testing.assert_allclose(state.P[:3, state.indices(8)], cross_robot, atol=1e-15)


def test_add_member_checks_its_arguments():
    state, founder = _state_with_body()
    with pytest.raises(ValueError, match="add_member"):
        state.add_member(8, 7, _member_block(founder, founder.structure))  # already in the state
    with pytest.raises(ValueError, match="add_member"):
        state.add_member(9, 42, _member_block(founder, founder.structure))  # no such founder


def test_grouping_records_world_points_and_the_founders_q():
    state, _ = _state_with_body()
    grouping = BodyGrouping(BodySettings())
    z = np.array([[1.0, 0.5, 0.2]])
    grouping.record(state, 0, [8], z, np.array([0.01 * np.eye(3)]))
    m, R, _ = grouping.points[8][0].world()
    c, s = np.cos(0.2), np.sin(0.2)
    np.testing.assert_allclose(m, [c * 1.0 - s * 0.5, s * 1.0 + c * 0.5, 0.2])
    np.testing.assert_allclose(R, 0.01 * np.eye(3), atol=1e-15)
    assert grouping.q[7][0] == pytest.approx(state.x[state.indices(7)][0])
    assert 8 not in grouping.q  # members have no q of their own


def test_config_reads_the_body_options():
    from stslam.config.slam import a_slam_from_config
    from stslam.errors import ConfigError
    assert a_slam_from_config(compose_config("dynamic_slam", ["++filters.a_slam.bodies=null"])).bodies is None
    params = a_slam_from_config(compose_config("dynamic_slam", ["++filters.a_slam.bodies.window=20"]))
    assert params.bodies == BodySettings(window=20)
    from stslam.articulation.hinge_axis import AxisTolerance
    tolerant = a_slam_from_config(compose_config("dynamic_slam", ["++filters.a_slam.bodies.max_angle_deg=5"]))
    assert tolerant.bodies.joint_tolerance == AxisTolerance(max_angle_deg=5.0)  # flat key, nested setting
    with pytest.raises(ConfigError, match=r"filters.a_slam.bodies.max_distance_m: expected a number > 0.0"):
        a_slam_from_config(compose_config("dynamic_slam", ["++filters.a_slam.bodies.max_distance_m=0"]))
    with pytest.raises(ValueError, match="max_angle_deg: expected a finite number > 0.0 and ≤ 90.0, got 95.0"):
        AxisTolerance(max_angle_deg=95.0)
    with pytest.raises(ConfigError, match=r"filters.a_slam.bodies: unknown option\(s\) nope"):
        a_slam_from_config(compose_config("dynamic_slam", ["++filters.a_slam.bodies.nope=1"]))


def _a_slam_policy(world_name: str, seed: int, *overrides):
    from stslam.config.robot import sensor_from_config
    from stslam.config.sim import world_from_config
    from stslam.config.slam import a_slam_from_config
    from stslam.sim.simulate import simulate
    from stslam.slam.a_slam import ASlamFramePolicy
    from stslam.slam.inputs import as_inputs
    from stslam.slam.loop import run_slam
    cfg = compose_config("dynamic_slam", [f"world={world_name}", *overrides])
    world = world_from_config(cfg)
    inputs = as_inputs(simulate(world, sensor_from_config(cfg), np.random.default_rng(seed)))
    policy = ASlamFramePolicy(a_slam_from_config(cfg), inputs)
    return world, policy, run_slam(inputs, policy)


def test_kitchen_parts_become_bodies():
    world, policy, track = _a_slam_policy("kitchen", 0, "filters.a_slam.bodies={}")
    members = {i: m.body for i, m in policy.landmarks.marks.items() if m.body is not None}
    assert len(members) >= 6 and len(set(members.values())) >= 3
    # Members sit on their founder's part. Not all: two static points that selection took for
    # movers drift together with the pose error, so they look rigid and both moving (seed 0: 7 of 8).
    same = [world.landmarks[i].body is not None and world.landmarks[i].body == world.landmarks[f].body
            for i, f in members.items()]
    assert np.mean(same) >= 0.8
    # No member on another moving part than its founder's. Seed 0 without the co-motion test joined two
    # top-drawer points to the dishwasher door: both move across the line between them, at other times,
    # so their distance stayed constant to second order and the rigidity test alone passed them.
    parts = world.landmarks
    assert not [(i, f) for i, f in members.items()
                if parts[i].body is not None and parts[f].body is not None and parts[i].body != parts[f].body]
    assert all(policy.landmarks.marks[f].body is None for f in members.values())  # founders are no members
    assert np.all(np.isfinite(track.poses_xytheta))


def test_bodies_of_one_point_change_nothing_where_no_two_points_move_together():
    # square_centred has one point per moving part: with bodies on, no pair passes the test
    # (resting points are never grouped), so A-SLAM runs exactly as without bodies.
    _, plain, track = _a_slam_policy("square_centred", 1)
    _, grouped, with_bodies = _a_slam_policy("square_centred", 1, "filters.a_slam.bodies={}")
    assert not any(m.body is not None for m in grouped.landmarks.marks.values())
    np.testing.assert_array_equal(track.poses_xytheta, with_bodies.poses_xytheta)


def test_a_bodys_observations_of_one_frame_update_it_jointly_as_one_after_another():
    """Founder and member stack the same block columns (SPEC 13), once per observation in the stacked H: on a
    linear problem (a slide, the heading exact) the joint update of their observations is the two in turn."""
    slide = BodyJoint("prismatic", np.array([2.0, 1.0, 0.5]), np.array([0.0, 1.0, 0.0]))
    founder_at, member_at = slide.point, slide.point + np.array([0.0, 0.0, 0.3])
    R = 0.02 ** 2 * np.eye(3)
    states = []
    for _ in range(3):
        state = BodySlamState(np.array([0.0, 0.0, 0.2]), np.diag([1e-4, 1e-4, 0.0]))
        founder = ArticulatedBlock(get_model("prismatic"), member_structure(slide, founder_at), 1, 0.01, 0.1)
        state.add_landmark(7, founder, observe(state.pose, member_position(slide, founder_at, 0.0, 0.2)), R)
        state.add_member(8, 7, _member_block(founder, member_structure(slide, member_at)))
        states.append(state)
    joint, in_turn, founder_only = states
    pose = np.array([0.01, -0.01, 0.2])
    zs = np.array([observe(pose, member_position(slide, founder_at, 0.0, 0.23)),
                   observe(pose, member_position(slide, member_at, 0.0, 0.21))])
    Rs = np.array([R, 2 * R])
    accepted, _ = joint.update_landmarks([7, 8], zs, Rs, 11.34)
    assert accepted.tolist() == [True, True]
    for i, z, R_i in zip([7, 8], zs, Rs, strict=True):
        assert in_turn.update_landmark(i, z, R_i).accepted
    np.testing.assert_allclose(joint.x, in_turn.x, atol=1e-12)
    np.testing.assert_allclose(joint.P, in_turn.P, atol=1e-14)
    founder_only.update_landmark(7, zs[0], R)
    q = joint.indices(7)[0]
    assert joint.P[q, q] < 0.9 * founder_only.P[q, q]  # the member's row informs the founder's q


def test_reanchor_detaches_a_member_that_would_sit_on_the_hinge():
    # A member carried onto its founder's new block exactly on the hinge axis has no offset to turn with:
    # it leaves the body as a static point (this path once called a helper its module did not define).
    from types import SimpleNamespace

    state, _ = _state_with_body()
    mark = SimpleNamespace(status="revolute", body=7, structure=object(), fitted=object(), r_scale=3.0,
                           refine_stopped=True)
    on_axis = HINGE.point + 0.2 * HINGE.direction
    BodyGrouping(BodySettings()).reanchor(state, 7, {8: on_axis}, {8: mark}, StaticPointBlock(0.0))
    assert state.founder_of(8) is None and isinstance(state.block(8), StaticPointBlock)
    assert (mark.status, mark.body, mark.structure, mark.fitted, mark.r_scale, mark.refine_stopped) == \
        ("static", None, None, None, 1.0, False)


def test_reanchor_detaches_a_member_on_the_hinge_of_a_block_of_another_size():
    # The founder's new block may be larger than the member's old view (structure_state consider/corrected
    # appends δ): the member on the new axis still leaves as a static point, where it was, with the
    # covariance its new view gives (a kitchen seed once raised a matmul shape error here).
    from types import SimpleNamespace

    from stslam.articulation.correction import correction_size
    from stslam.slam.blocks import CorrectedArticulatedBlock

    state, founder = _state_with_body()
    new = CorrectedArticulatedBlock(founder.model, founder.structure, 1, 0.01, 0.1, consider=True)
    extra = correction_size("revolute")
    J = np.vstack([np.eye(founder.size), np.zeros((extra, founder.size))])
    prior = np.zeros((new.size, new.size))
    prior[founder.size:, founder.size:] = 1e-4 * np.eye(extra)
    state.replace_block(7, new, J @ state.block_mean(7), J, prior)
    near_axis = HINGE.point + np.array([0.004, 0.002, 0.3])  # 4.5 mm off the axis
    mark = SimpleNamespace(status="revolute", body=7, structure=object(), fitted=object(), r_scale=3.0,
                           refine_stopped=True)
    BodyGrouping(BodySettings()).reanchor(state, 7, {8: near_axis}, {8: mark}, StaticPointBlock(0.0))
    assert state.founder_of(8) is None and isinstance(state.block(8), StaticPointBlock)
    m, cov = state.landmark_position(8)
    np.testing.assert_allclose(m, near_axis, atol=1e-12)
    # it turns on a 1 cm circle at most (the founder's φ variance times ≤ (1 cm)²) and reads the joint's δ:
    # the centre shift c (3 × 1e-4) and the tilt (2 × 1e-4 times its lever from the founder's centre, squared)
    phi_var = state.P[state.indices(7)[0], state.indices(7)[0]]
    lever = np.linalg.norm(near_axis - founder.structure.centre_world)
    assert 3e-4 < np.trace(cov) <= 1.01 * (0.01 ** 2 * phi_var + 3e-4 + 2e-4 * lever ** 2)
    assert np.all(np.linalg.eigvalsh(state.P) > -1e-12)


class _Mark:
    def __init__(self, status):
        self.status, self.r_scale = status, 1.0


def test_the_bodies_pose_is_the_one_the_static_points_alone_left():
    """``_update``'s ``between`` sees the pose after the frame's static points and before the articulated
    landmarks' own updates (BodySettings.evidence_pose "static"), and BodyGrouping.record keeps that pose."""
    from stslam.slam.a_slam import _update

    state, founder = _state_with_body()
    R = 0.02 ** 2 * np.eye(3)
    statics = {1: np.array([2.0, -1.0, 0.5]), 2: np.array([2.5, 1.0, 1.0])}
    for i, z in statics.items():
        state.add_landmark(i, StaticPointBlock(0.0), z, R)
    state.P[:3, :3] += np.diag([0.05 ** 2, 0.05 ** 2, 0.01 ** 2])  # the robot has moved since
    phi = state.x[state.indices(7)][0]
    door = founder.model.position(founder.structure, np.array([phi + 0.15]))  # the door turned on
    ids = [1, 2, 7]
    zs = np.array([statics[1] + [0.03, 0.0, 0.0], statics[2] + [0.03, 0.0, 0.0], observe(state.pose, door)])
    Rs = np.repeat(R[None], 3, axis=0)
    expected = state.copy()
    expected.update_landmarks([1, 2], zs[:2], Rs[:2])  # the static points alone
    seen = []
    outcome = _update(state, ids, zs, Rs, {1: _Mark("static"), 2: _Mark("static"), 7: _Mark("revolute")}, set(),
                      16.0, 0.999, between=lambda: seen.append((state.pose, state.pose_cov)))
    assert all(outcome.values()) and len(seen) == 1
    np.testing.assert_allclose(seen[0][0], expected.pose, atol=1e-12)
    np.testing.assert_allclose(seen[0][1], expected.pose_cov, atol=1e-15)
    assert np.linalg.norm(state.pose - seen[0][0]) > 1e-4  # the door's own update moved the pose further
    grouping = BodyGrouping(BodySettings())
    grouping.record(state, 4, ids, zs, Rs, seen[0])
    np.testing.assert_array_equal(grouping.points[7][4].pose, seen[0][0])
    grouping.record(state, 5, ids, zs, Rs)  # no pose given: the state's posterior
    np.testing.assert_array_equal(grouping.points[7][5].pose, state.pose)
