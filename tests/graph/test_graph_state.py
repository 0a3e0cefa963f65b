"""The iSAM2 state: a small graph with a known answer, and agreement with the EKF on a linear-Gaussian problem."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gtsam")

from stslam.graph.run import run_filter_isam2  # noqa: E402
from stslam.graph.state import GraphState, Isam2Settings  # noqa: E402
from stslam.robot.motion import motion_jacobians, move  # noqa: E402
from stslam.robot.sensor import observe  # noqa: E402
from stslam.slam.blocks import ConstantVelocityPointBlock, StaticPointBlock  # noqa: E402
from stslam.slam.filters import FilterSpec  # noqa: E402
from stslam.slam.inputs import SlamInputs  # noqa: E402
from linear_scene import straight_line_inputs  # noqa: E402
from stslam.slam.loop import BlockPolicy, run_slam  # noqa: E402


def test_odometry_only_gives_the_propagated_covariance_and_noise_free_data_the_truth():
    floor = 1e-5
    settings = Isam2Settings(floor_sigma=floor)
    x0, u, S, dt = np.array([1.0, 2.0, 0.3]), np.array([0.5, 0.2]), np.diag([0.01, 0.004]), 1.0
    state = GraphState(x0, np.zeros((3, 3)), motion_order=1, settings=settings)
    state.predict(u, S, dt)
    G, V = motion_jacobians(x0, u, dt)
    expected = G @ (floor**2 * np.eye(3)) @ G.T + V @ S @ V.T + floor**2 * np.eye(3)
    np.testing.assert_allclose(state.pose, move(x0, u, dt), atol=1e-12)
    np.testing.assert_allclose(state.pose_cov, expected, rtol=1e-8, atol=1e-14)
    # A landmark seen without noise from both poses: the estimate stays the truth.
    m = np.array([2.0, 3.0, 0.4])
    state.add_landmark(7, StaticPointBlock(), observe(state.pose, m), 1e-4 * np.eye(3))
    state.predict(u, S, dt)
    x2 = move(move(x0, u, dt), u, dt)
    state.update_landmarks([7], observe(x2, m).reshape(1, 3), 1e-4 * np.eye(3))
    np.testing.assert_allclose(state.pose, x2, atol=1e-10)
    np.testing.assert_allclose(state.block_mean(7), m, atol=1e-10)
    assert np.all(np.linalg.eigvalsh(state.pose_cov) < np.linalg.eigvalsh(expected).max() * 10)


def _linear_inputs(seed=0, n=15):
    """Five points, each unseen every fourth frame; point 4 moves with a constant velocity."""
    points = np.array([[1.0, 1.0, 0.2], [2.0, -1.0, 0.5], [1.5, 0.5, 0.0], [2.5, 1.5, 0.3], [0.5, -0.8, 0.1]])
    velocity = np.array([0.01, -0.02, 0.0])

    def world_at(k):
        seen = [j for j in range(len(points)) if (k + j) % 4 != 0]
        return seen, np.array([points[j] + (k * velocity if j == 4 else 0.0) for j in seen])

    return straight_line_inputs(world_at, n, 0.04, seed)


def _block(i):
    if i == 4:
        return ConstantVelocityPointBlock(0.003, 0.05)
    return StaticPointBlock(0.0 if i % 2 else 0.002)


def test_both_back_ends_agree_on_a_linear_gaussian_problem():
    inputs = _linear_inputs()
    spec = FilterSpec("mixed", lambda _: BlockPolicy(_block), motion_order=1)
    ekf = run_slam(inputs, spec.policy_for(inputs), motion_order=1)
    graph = run_filter_isam2(spec, inputs, Isam2Settings(floor_sigma=1e-7))
    np.testing.assert_allclose(graph.online_poses_xytheta, ekf.poses_xytheta, atol=1e-9, rtol=0)
    np.testing.assert_allclose(graph.online_pose_covs, ekf.pose_covs, atol=1e-9, rtol=0)
    # The smoother's last pose is the filter's; earlier ones use later data.
    np.testing.assert_allclose(graph.poses_xytheta[-1], ekf.poses_xytheta[-1], atol=1e-9, rtol=0)
    assert np.abs(graph.poses_xytheta[:-1] - ekf.poses_xytheta[:-1]).max() > 1e-6


def test_both_back_ends_agree_when_observing_every_third_frame():
    # observe_every: observations enter at frames 0, 3, 6, ... only, in the graph as in the EKF loop;
    # the linear-Gaussian problem then still has one answer, the EKF's (SPEC 14).
    inputs = _linear_inputs(seed=2, n=16)
    spec = FilterSpec("mixed", lambda _: BlockPolicy(_block), motion_order=1)
    ekf = run_slam(inputs, spec.policy_for(inputs), motion_order=1, observe_every=3)
    graph = run_filter_isam2(spec, inputs, Isam2Settings(floor_sigma=1e-7, observe_every=3))
    np.testing.assert_allclose(graph.online_poses_xytheta, ekf.poses_xytheta, atol=1e-9, rtol=0)
    np.testing.assert_allclose(graph.online_pose_covs, ekf.pose_covs, atol=1e-9, rtol=0)
    every = run_slam(inputs, spec.policy_for(inputs), motion_order=1)
    assert np.abs(every.poses_xytheta - ekf.poses_xytheta).max() > 1e-6  # frames 1, 2, 4, ... were left out
    with pytest.raises(ValueError, match="observe_every must be an integer ≥ 1"):
        Isam2Settings(observe_every=0)


def test_gates_reject_what_the_ekf_rejects():
    inputs = _linear_inputs(seed=1)
    moved = [z.copy() for z in inputs.observations]
    for k in range(8, inputs.n_frames):  # landmark 2 jumps by 0.5 m: its observations fail the χ² gate
        seen = list(inputs.observation_ids[k])
        if 2 in seen:
            moved[k][seen.index(2)] += [0.5, 0.0, 0.0]
    bad = SlamInputs(inputs.initial_pose_xytheta, inputs.controls_vw, inputs.control_covs, inputs.dts_s,
                     inputs.observation_ids, tuple(moved), inputs.observation_covs)
    spec = FilterSpec("gated", lambda _: BlockPolicy(lambda i: StaticPointBlock(), 11.34), motion_order=1)
    ekf = run_slam(bad, spec.policy_for(bad), motion_order=1)
    graph = run_filter_isam2(spec, bad, Isam2Settings(floor_sigma=1e-7))
    assert ekf.n_rejected > 0 and graph.n_rejected == ekf.n_rejected
    np.testing.assert_allclose(graph.online_poses_xytheta, ekf.poses_xytheta, atol=1e-9, rtol=0)


def test_a_structure_variable_corrects_a_wrongly_fitted_line():
    from stslam.articulation.models import PrismaticStructure, get_model
    from stslam.geometry import rotation_z
    from stslam.graph.structure import corrected_position
    from stslam.slam.blocks import ArticulatedBlock

    start, step = np.array([1.0, 2.0, 0.3]), 0.05 * np.array([1.0, 0.0, 0.0])  # the true line, 1 m seen
    wrong = PrismaticStructure(start + [0.0, 0.02, 0.0], rotation_z(np.radians(5.0)) @ [1.0, 0.0, 0.0], 0.0)
    block = ArticulatedBlock(get_model("prismatic"), wrong, 1, 1e-3, 0.1)
    R, pose = 1e-6 * np.eye(3), np.zeros(3)
    state = GraphState(pose, np.zeros((3, 3)), motion_order=1,
                       settings=Isam2Settings(floor_sigma=1e-6, structure="variable"))
    state.add_landmark(0, block, observe(pose, start), R)
    for k in range(1, 21):  # the robot stands still (tiny odometry noise); the point slides
        state.predict(np.zeros(2), 1e-10 * np.eye(2), 1.0)
        state.update_landmarks([0], observe(pose, start + k * step).reshape(1, 3), R)
        state.pose  # as the frame loop does: iSAM2 takes each frame's factors at once
    state.smoothed()
    delta = state.value(state._structures.key(state, block))
    for k in (0, 10, 20):  # every true point lies on the corrected line
        m, w, _ = corrected_position("prismatic", wrong, 0.0, delta)
        direction = w / np.linalg.norm(w)  # ∂f/∂q = w, the line's direction unnormalised
        d = start + k * step - m
        assert np.linalg.norm(d - (d @ direction) * direction) < 1e-3
    assert np.degrees(np.arccos(abs(direction @ [1.0, 0.0, 0.0]))) < 0.1


def _door(radius=0.8, centre=(2.0, 1.0, 0.5)):
    """A revolute structure fitted on a quarter circle in the horizontal plane, and the point at φ."""
    from stslam.articulation.models import get_model

    phis = np.linspace(0.0, np.pi / 2, 12)
    pts = np.array(centre) + radius * np.column_stack([np.cos(phis), np.sin(phis), np.zeros_like(phis)])
    model = get_model("revolute")
    structure = model.fit(pts)
    return model, structure, lambda phi: model.position(structure, np.array([phi]))


def test_a_refit_reread_across_a_long_gap_keeps_the_turns_the_rate_made():
    from stslam.slam.blocks import ArticulatedBlock

    model, structure, position = _door()
    rate, pose, R = 0.5, np.zeros(3), 1e-6 * np.eye(3)
    phi0 = float(model.motion_variable(structure, position(0.2)[None])[0, 0])
    block = ArticulatedBlock(model, structure, 1, 1e-3, 1.0)
    state = GraphState(pose, np.zeros((3, 3)), motion_order=1,
                       settings=Isam2Settings(floor_sigma=1e-6, structure="fixed"))
    seen = lambda k: observe(pose, position(phi0 + rate * k)).reshape(1, 3)  # noqa: E731
    state.add_landmark(0, block, seen(0)[0], R)
    for k in range(1, 42):  # seen at frames 0-2, then not until frame 40 (19 rad later), refitted there
        state.predict(np.zeros(2), 1e-10 * np.eye(2), 1.0)
        if k <= 2 or k >= 40:
            state.update_landmarks([0], seen(k), R)
        if k == 40:
            state.replace_block(0, block, state.block_mean(0), np.eye(2), np.zeros((2, 2)))
        state.pose
    for k in (0, 2, 40, 41):  # the re-read at frame 41 reads every frame's φ on the same turns as the rate
        key, _ = state._chains[0].at[k]
        assert state.value(key)[0] == pytest.approx(phi0 + rate * k, abs=1e-2)
        assert state.value(key)[1] == pytest.approx(rate, abs=1e-3)


def test_the_frames_prior_marginal_is_propagated_without_an_update_and_equals_isam2s():
    # GraphState.joint: the new pose and the blocks carried to the frame are predictions from variables
    # iSAM2 holds; their joint marginal T P Tᵀ + Q must be the one iSAM2 gives once it has the factors
    # (a linear transition, odometry linearised at the same point). 1e-9: float rounding of two routes.
    inputs = _linear_inputs(seed=3, n=6)
    state = GraphState(inputs.initial_pose_xytheta, np.zeros((3, 3)), motion_order=2,
                       settings=Isam2Settings(floor_sigma=1e-6))
    policy = BlockPolicy(_block)
    for k in range(4):
        if k:
            state.predict(inputs.controls_vw[k - 1], inputs.control_covs[k - 1], float(inputs.dts_s[k - 1]))
        ids = [int(i) for i in inputs.observation_ids[k]]
        known = [j for j, i in enumerate(ids) if i in state]
        if known:
            state.update_landmarks([ids[j] for j in known], inputs.observations[k][known],
                                   inputs.observation_covs[k][known])
        for j, i in enumerate(ids):
            if i not in state:
                policy.add_landmark(state, i, inputs.observations[k][j], inputs.observation_covs[k][j])
        state.pose
    state.predict(inputs.controls_vw[3], inputs.control_covs[3], float(inputs.dts_s[3]))
    keys = [state._advance(i) for i in (0, 2, 4)]  # a static point (one variable), a walking one, a moving one
    from stslam.graph.state import pose_key

    keys = [pose_key(state.k), *keys]
    n_updates = state._solver._isam.getFactorsUnsafe().size()
    predicted = state.joint(keys)
    assert state._solver._isam.getFactorsUnsafe().size() == n_updates and state._graph.size() > 0  # no update
    state._flush()
    np.testing.assert_allclose(predicted, state._solver.joint(keys), atol=1e-9, rtol=1e-7)


@pytest.mark.parametrize("sigma", [0.3, 10.0])
def test_a_structure_correction_seen_at_one_position_keeps_its_prior_where_unobserved(sigma):
    """A line observed at one q (a drawer at rest) does not determine its tilt: δ's (u, v) keep the prior's
    std ``structure_sigma`` (Isam2Settings), which the observations leave untouched in that direction."""
    from stslam.articulation.models import PrismaticStructure, get_model
    from stslam.slam.blocks import ArticulatedBlock

    line = PrismaticStructure(np.array([1.0, 2.0, 0.3]), np.array([1.0, 0.0, 0.0]), 0.0)
    block = ArticulatedBlock(get_model("prismatic"), line, 0, 1e-3, 0.1)
    R, pose = 1e-4 * np.eye(3), np.zeros(3)
    state = GraphState(pose, np.zeros((3, 3)), motion_order=1,
                       settings=Isam2Settings(floor_sigma=1e-6, structure="variable", structure_sigma=sigma))
    state.add_landmark(0, block, observe(pose, line.p0), R)
    state.pose
    key = state._structures.key(state, block)
    cov = state._solver.marginal(key)
    # At q = 0 the tilt (u, v) moves nothing (∂f/∂(u, v) = q e₁,₂): its marginal is the prior's alone
    # (rtol: the floor's 1e-6 std added to the other factors' covariances, far below σ²).
    np.testing.assert_allclose(np.diag(cov)[2:], sigma**2, rtol=1e-6)
    assert np.all(np.diag(cov)[:2] < 1e-3)  # the shift across the line is what the observation gives


def test_the_structure_priors_are_loosened_after_the_last_frame():
    """``structure_sigma_final``: the δ prior (std ``structure_sigma`` during the run) ends with that std, so the
    tilt no observation spans has it as its smoothed marginal, and the observed shift keeps what its
    observation gives."""
    from stslam.articulation.models import PrismaticStructure, get_model
    from stslam.slam.blocks import ArticulatedBlock

    line = PrismaticStructure(np.array([1.0, 2.0, 0.3]), np.array([1.0, 0.0, 0.0]), 0.0)
    block = ArticulatedBlock(get_model("prismatic"), line, 0, 1e-3, 0.1)
    R, pose = 1e-4 * np.eye(3), np.zeros(3)
    settings = Isam2Settings(floor_sigma=1e-6, structure="variable", structure_sigma=0.1, structure_sigma_final=3.0,
                             regate_probability=None)
    state = GraphState(pose, np.zeros((3, 3)), motion_order=1, settings=settings)
    state.add_landmark(0, block, observe(pose, line.p0), R)
    state.pose
    key = state._structures.key(state, block)
    np.testing.assert_allclose(np.diag(state._solver.marginal(key))[2:], 0.1**2, rtol=1e-6)  # the run's prior
    state.smoothed()
    cov = state._solver.marginal(key)
    # The tilt's marginal is the loosened prior alone (rtol: as above, the floor is far below σ²) ...
    np.testing.assert_allclose(np.diag(cov)[2:], 3.0**2, rtol=1e-6)
    # ... and the shift across the line is still what the observation gives (σ 1 cm: well under the old prior).
    assert np.all(np.diag(cov)[:2] < 1e-3)
    assert len(state._structures._priors[key].factor_indices) == 1  # the old prior is gone: one prior, the new one
    with pytest.raises(ValueError, match="structure_sigma_final must be None or > 0"):
        Isam2Settings(structure_sigma_final=0.0)


class _Spy:
    """Stands in for gtsam.ISAM2: records, per update, whether it was forced to relinearise and how many
    variables it relinearised."""

    def __init__(self, isam, state, log):
        self._isam, self._state, self._log = isam, state, log

    def update(self, *args, force_relinearize=False, **kwargs):
        result = self._isam.update(*args, force_relinearize=force_relinearize, **kwargs)
        self._log.append((self._state.k, force_relinearize, int(result.getVariablesRelinearized())))
        return result

    def __getattr__(self, name):
        return getattr(self._isam, name)


def test_one_update_per_frame_and_relinearisation_on_a_frame_schedule():
    inputs = _linear_inputs(seed=3, n=15)
    log: list = []
    settings = Isam2Settings(floor_sigma=1e-7, relinearize_threshold=1e-12, relinearize_threshold_m=1e-12,
                             relinearize_frames=4)
    state = GraphState(inputs.initial_pose_xytheta, np.zeros((3, 3)), 1, settings)
    state._solver._isam = _Spy(state._solver._isam, state, log)
    run_slam(inputs, BlockPolicy(_block), motion_order=1, state=state)
    assert [k for k, _, _ in log] == list(range(inputs.n_frames))  # one iSAM2 update per frame
    assert [k for k, force, _ in log if force] == [0, 4, 8, 12]  # a relinearisation check every 4 frames
    assert all(n > 0 for k, force, n in log if force and k > 0)  # at a threshold of 1e-12 each relinearises
    assert all(n == 0 for _, force, n in log if not force)  # and no other update does
    with pytest.raises(ValueError, match="relinearize_frames must be None or an integer ≥ 1"):
        Isam2Settings(relinearize_frames=0)


def test_a_new_structure_correction_is_part_of_the_frames_prior_marginal_without_an_update():
    # A refit's δ is first made at the frame's gate (observing.StructureKeys): its marginal is its prior,
    # uncorrelated with the rest, so the gate needs no iSAM2 update for it (prior.Predictions.record_prior).
    from stslam.articulation.models import PrismaticStructure, get_model
    from stslam.graph.state import pose_key
    from stslam.slam.blocks import ArticulatedBlock

    drawer = PrismaticStructure(np.array([1.0, 1.0, 0.2]), np.array([1.0, 0.0, 0.0]), 0.0)
    sigma = 0.1
    state = GraphState(np.zeros(3), np.zeros((3, 3)), motion_order=1,
                       settings=Isam2Settings(floor_sigma=1e-7, structure="variable", structure_sigma=sigma))
    block = ArticulatedBlock(get_model("prismatic"), drawer, 1, 0.02, 0.05)
    R = 1e-4 * np.eye(3)
    state.add_landmark(1, block, observe(np.zeros(3), np.array([1.2, 1.0, 0.2])), R)
    state.add_landmark(2, StaticPointBlock(), observe(np.zeros(3), np.array([2.0, -1.0, 0.5])), R)
    state.pose
    refit = ArticulatedBlock(get_model("prismatic"), PrismaticStructure(drawer.p0 + [0.0, 0.01, 0.0], drawer.direction,
                                                                          0.0), 1, 0.02, 0.05)
    x = state.block_mean(1)
    state.replace_block(1, refit, x, np.eye(x.size), np.zeros((x.size, x.size)))  # a refit: its δ is not made yet
    state.pose
    state.predict(np.array([0.2, 0.0]), np.diag([0.01**2, 1e-6]), 1.0)
    keys = [pose_key(state.k), state._advance(1), state._advance(2)]
    n_factors = state._solver._isam.getFactorsUnsafe().size()
    delta = state._structures.key(state, refit)
    assert not state._solver.holds(delta)
    predicted = state.joint([*keys, delta])
    assert state._solver._isam.getFactorsUnsafe().size() == n_factors  # no update
    size = state.value(delta).size
    np.testing.assert_array_equal(predicted[-size:, :-size], 0.0)
    np.testing.assert_array_equal(predicted[-size:, -size:], sigma**2 * np.eye(size))
    state._flush()
    np.testing.assert_allclose(predicted, state._solver.joint([*keys, delta]), atol=1e-9, rtol=1e-7)
