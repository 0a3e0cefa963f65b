"""A-SLAM with its structures' corrections in the EKF state (structure_state: corrected, SPEC 6.3(b))."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.slam.bodies.joint import BodyJoint, member_structure
from stslam.articulation.models import get_model
from stslam.errors import ConfigError
from stslam.robot.sensor import observe
from stslam.sim.worlds import revolute_structure
from stslam.slam.blocks import ArticulatedBlock, CorrectedArticulatedBlock
from stslam.slam.core import SlamState

from conftest import compose_config

DOOR = revolute_structure(np.array([2.0, 3.0, 1.0]), np.array([0.0, 0.0, 1.0]), [1.0, 0.0, 0.0], 0.8)


def test_a_corrected_block_reads_delta_and_keeps_it_constant():
    block = CorrectedArticulatedBlock(get_model("revolute"), DOOR, 1, 0.01, 0.1)
    assert block.motion_size == 2 and block.size == 8
    x = np.array([0.3, 0.05, 0.01, -0.02, 0.03, 0.02, -0.01, 0.04])
    m, dm_dx = block.position(x)
    eps = 1e-7
    numeric = np.column_stack([(block.position(x + eps * e)[0] - m) / eps for e in np.eye(8)])
    np.testing.assert_allclose(dm_dx, numeric, atol=1e-5)
    F, Q = block.transition(1.0)
    np.testing.assert_array_equal(F[2:, 2:], np.eye(6))
    np.testing.assert_array_equal(Q[2:, :], 0.0)
    # A member's view, at the founder's size, reads q on its own structure and the joint's part of δ.
    handle = member_structure(BodyJoint("revolute", np.array([2.0, 3.0, 1.0]), np.array([0.0, 0.0, 1.0])),
                              np.array([2.7, 3.0, 0.8]))
    view = block.member_view(handle)
    plain = ArticulatedBlock(get_model("revolute"), handle, 1, 0.01, 0.1)
    m_view, d_view = view.position(x)
    at_fit = x.copy()
    at_fit[2:] = 0.0
    np.testing.assert_allclose(view.position(at_fit)[0], plain.position(x[:2])[0])
    numeric = np.column_stack([(view.position(x + eps * e)[0] - m_view) / eps for e in np.eye(8)])
    np.testing.assert_allclose(d_view, numeric, atol=1e-5)
    assert view.size == 8 and not d_view[:, 1].any() and not d_view[:, 7].any()  # not q̇, not the founder's ρ
    # A slip has no place in a corrected block: its size and transition would leave it out.
    with pytest.raises(ValueError, match="sigma_slip"):
        CorrectedArticulatedBlock(get_model("revolute"), DOOR, 1, 0.01, 0.1, sigma_slip=0.1)


@pytest.mark.parametrize("name", ["revolute", "prismatic"])
def test_a_member_moves_with_its_founders_corrected_joint(name):
    """SPEC 13: a body is rigid, so a member's point keeps its place relative to the founder's corrected
    joint: the member sits where the founder's correction, applied as the same rigid motion, carries it."""
    from stslam.articulation.models import PrismaticStructure
    if name == "revolute":
        founder = revolute_structure(np.array([2.0, 3.0, 1.0]), np.array([0.2, -0.1, 1.0]) / np.sqrt(1.05),
                                     [1.0, 0.0, 0.0], 0.8)
        joint = BodyJoint("revolute", founder.centre_world, founder.normal)
        delta = np.array([0.02, -0.01, 0.03, 0.04, -0.02, 0.0])
    else:
        founder = PrismaticStructure(p0=np.array([1.0, 0.5, 0.7]), direction=np.array([0.6, 0.8, 0.0]),
                                     residual_m=0.0)
        joint = BodyJoint("prismatic", founder.p0, founder.direction)
        delta = np.array([0.0, 0.0, 0.05, -0.03])
    block = CorrectedArticulatedBlock(get_model(name), founder, 0, 0.01, 0.1)
    member = member_structure(joint, np.array([2.5, 3.4, 1.3]))
    view = block.member_view(member)
    q = 0.4
    # The member's point, and a founder's point on the member's spot, read through their own corrections:
    # both are carried by one rigid motion (one correction of the shared joint), so their offset is kept
    # up to the founder's own offset entries (zero here).
    x = np.r_[q, delta]
    ref = np.r_[q, np.zeros_like(delta)]
    moved_member = view.position(x)[0] - view.position(ref)[0]
    moved_founder = block.position(x)[0] - block.position(ref)[0]
    if name == "prismatic":  # a tilt w moves a point by q·Δw whatever the line's offset
        np.testing.assert_allclose(moved_member, moved_founder, atol=1e-12)
    else:  # the body turns about the founder's centre: the change is c + (R(ω) − I)·(lever)
        from stslam.geometry import rotation_about_axis
        omega = delta[3] * founder.v1 + delta[4] * founder.v2
        R = rotation_about_axis(omega / np.linalg.norm(omega), np.linalg.norm(omega))
        lever = view.position(ref)[0] - founder.centre_world
        np.testing.assert_allclose(moved_member, delta[:3] + (R - np.eye(3)) @ lever, atol=1e-12)


def test_coupling_to_the_pose_is_placing_the_correction_through_it():
    state = SlamState(np.array([0.1, -0.2, 0.3]), np.diag([1e-3, 2e-3, 1e-4]))
    block = ArticulatedBlock(get_model("revolute"), DOOR, 0, 0.01, 0.1)
    state.add_landmark(4, block, observe(state.pose, block.model.position(DOOR, np.array([0.3]))), 1e-3 * np.eye(3))
    corrected = CorrectedArticulatedBlock(block.model, DOOR, 0, 0.01, 0.1)
    state.replace_block(4, corrected, np.r_[state.block_mean(4), np.zeros(6)], np.eye(7, 1), np.zeros((7, 7)))
    A, extra = np.arange(18.0).reshape(6, 3) / 10.0, 1e-4 * np.eye(6)
    state.couple_to_pose(4, np.arange(1, 7), A, extra)
    rows = state.indices(4)[1:]
    np.testing.assert_allclose(state.P[np.ix_(rows, rows)], A @ state.P[:3, :3] @ A.T + extra)
    np.testing.assert_allclose(state.P[rows, :3], A @ state.P[:3, :3])
    assert np.linalg.eigvalsh(state.P).min() > -1e-12


def _run(world_name: str, seed: int, *overrides, observer=None):
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
    return policy, run_slam(inputs, policy, observer=observer), world


def test_kitchen_bodies_run_with_corrected_founders():
    policy, track, world = _run("kitchen", 0, "filters.a_slam.structure_state=corrected")
    marks = policy.landmarks.marks
    corrected = [i for i, m in marks.items() if m.status in ("prismatic", "revolute") and m.body is None
                 and m.r_scale < m.fixed_scale]
    assert corrected  # settled founders: their κ is 0, their members' stays
    # Members keep fixed structures on their founder's q, and the founder's κ at their joining.
    assert any(m.body in corrected and m.r_scale > marks[m.body].r_scale for m in marks.values())
    err = np.linalg.norm(track.poses_xytheta[:, :2] - world.poses_xytheta[:, :2], axis=1)
    assert np.all(np.isfinite(track.poses_xytheta)) and err.max() < 0.2


def test_kitchen_consider_corrections_are_never_updated_but_carried():
    from stslam.slam.blocks import CorrectedArticulatedBlock
    seen = {}

    def observe(k, state):
        for i in state.landmark_ids:
            block = state.block(i)
            if isinstance(block, CorrectedArticulatedBlock):
                assert block.consider
                idx = state.indices(i)[block.motion_size:]
                assert np.all(state.x[idx] == 0.0)  # a consider δ stays at the fit, exactly
                seen[i] = float(np.trace(state.P[np.ix_(idx, idx)]))

    policy, track, world = _run("kitchen", 0, "filters.a_slam.structure_state=consider", observer=observe)
    assert seen and all(v > 0.0 for v in seen.values())  # their covariance is in P
    err = np.linalg.norm(track.poses_xytheta[:, :2] - world.poses_xytheta[:, :2], axis=1)
    assert np.all(np.isfinite(track.poses_xytheta)) and err.max() < 0.2  # as the corrected run above


def test_config_reads_the_structure_state():
    from stslam.config.slam import a_slam_from_config
    params = a_slam_from_config(compose_config("dynamic_slam", ["filters.a_slam.structure_state=corrected",
                                                                "filters.a_slam.structure_prior=sensor"]))
    assert (params.structure_state, params.structure_prior) == ("corrected", "sensor")
    with pytest.raises(ConfigError, match=r"filters.a_slam.structure_state: expected one of fixed, corrected, consider"):
        a_slam_from_config(compose_config("dynamic_slam", ["filters.a_slam.structure_state=yes"]))
