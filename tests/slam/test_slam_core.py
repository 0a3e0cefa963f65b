"""The shared SLAM core, its landmark blocks and the O(n²) Kalman routes (SPEC 6)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.kalman import ekf
from stslam.articulation.models import get_model
from stslam.config.robot import sensor_from_config
from stslam.config.sim import world_from_config
from stslam.config.slam import filter_params_from_config
from stslam.errors import ConfigError
from stslam.robot.sensor import observation_jacobians, observe, point_from_observation
from stslam.sim.simulate import simulate
from stslam.slam.consistency import pose_nees
from stslam.slam import (ArticulatedBlock, ConstantVelocityPointBlock, SlamState, StaticPointBlock,
                         make_filter, run_filter)
from stslam.slam.filters import EkfSlamParams
from stslam.sim.worlds import revolute_structure

from conftest import compose_config

# Two routes through the same float64 algebra on O(1) numbers differ by round-off (~1e-15);
# 1e-12 is filterpy's "two routes agree" tolerance.
ROUTES = 1e-12


def _spd(rng, n):
    A = rng.normal(size=(n, n))
    return A @ A.T + 0.1 * np.eye(n)


def test_sparse_update_equals_dense_joseph_update():
    rng = np.random.default_rng(11)
    n = 13
    x, P = rng.normal(size=n), _spd(rng, n)
    cols = np.array([0, 1, 2, 7, 8, 9, 10])
    H_cols = rng.normal(size=(6, cols.size))
    H = np.zeros((6, n))
    H[:, cols] = H_cols
    R, y = np.diag(rng.uniform(0.1, 0.5, 6)), rng.normal(size=6)
    dense, sparse = ekf.update(x, P, y, H, R), ekf.update_sparse(x, P, y, cols, H_cols, R)
    np.testing.assert_allclose(sparse.x, dense.x, atol=ROUTES)
    np.testing.assert_allclose(sparse.P, dense.P, atol=ROUTES)
    assert sparse.log_likelihood == pytest.approx(dense.log_likelihood, abs=ROUTES)
    gated = ekf.update_sparse(x, P, y, cols, H_cols, R, max_nis=0.5 * dense.nis)
    assert not gated.accepted and gated.x is x and gated.P is P and gated.nis == pytest.approx(dense.nis)


def test_block_prediction_equals_dense_prediction():
    rng = np.random.default_rng(12)
    n = 11
    x, P = rng.normal(size=n), _spd(rng, n)
    F0, F1 = rng.normal(size=(3, 3)), rng.normal(size=(2, 2))
    Q0, Q1 = 0.1 * np.eye(3), np.array([[0.2, 0.05], [0.05, 0.3]])
    F, Q = np.eye(n), np.zeros((n, n))
    for index, Fi, Qi in (([0, 1, 2], F0, Q0), ([4, 5], F1, Q1), ([8, 9], F1, Q1)):
        F[np.ix_(index, index)], Q[np.ix_(index, index)] = Fi, Qi
    Q[6, 6] = 0.7  # a block with identity F and noise only
    x_dense, P_dense = ekf.predict(x, P, F, Q)
    blocks = [(np.arange(3), F0, Q0, None), (np.array([[4, 5], [8, 9]]), F1, Q1, None),
              (np.array([6]), None, np.array([[0.7]]), None)]
    x_blocks, P_blocks = ekf.predict_blocks(x, P, blocks)
    np.testing.assert_allclose(x_blocks, x_dense, atol=ROUTES)
    np.testing.assert_allclose(P_blocks, P_dense, atol=ROUTES)


@pytest.mark.parametrize("order", [1, 2])
def test_robot_prediction_adds_the_second_order_control_noise(order):
    from stslam.robot.motion import control_noise_cov, motion_jacobians, second_order_motion_noise

    pose, control = np.array([0.4, -0.3, 2.2]), np.array([0.21, 0.063])
    S = control_noise_cov(control, [0.1, 0.05, 0.05, 0.1])
    state = SlamState(pose, np.zeros((3, 3)), motion_order=order)
    state.predict(control, S, 1.0)
    _, V = motion_jacobians(pose, control, 1.0)
    expected = V @ S @ V.T + (second_order_motion_noise(pose, control, S, 1.0) if order == 2 else 0.0)
    np.testing.assert_allclose(state.pose_cov, expected, atol=1e-15)
    # First order leaves the covariance rank 2 (two controls); Q₂ makes it full rank.
    assert np.linalg.matrix_rank(state.pose_cov, tol=1e-12) == (3 if order == 2 else 2)
    with pytest.raises(ValueError, match="motion_order"):
        SlamState(pose, np.zeros((3, 3)), motion_order=3)


def _map_cost_gradient(state, x_prior, P_prior, landmark_ids, zs, R):
    """∇ of (x − x⁻)ᵀP⁻⁻¹(x − x⁻) + Σ (z − h(x))ᵀR⁻¹(z − h(x)) at the state's x (halved)."""
    grad = np.linalg.solve(P_prior, state.x - x_prior)
    for i, z in zip(landmark_ids, zs):
        z_hat, cols, H_cols = state.predict_observation(i)
        grad[cols] -= H_cols.T @ np.linalg.solve(R, z - z_hat)
    return grad


def test_iterated_update_reaches_the_map_of_the_update():
    """One EKF update leaves the MAP cost's gradient large when the heading is uncertain; the
    iterated update (Gauss–Newton from the same prior) drives it to ~0 and keeps the first
    linearisation's NIS for the gate."""
    rng = np.random.default_rng(21)
    results = {}
    for iterations in (1, 4, 12):
        state = SlamState(np.array([0.3, -0.2, 0.5]), np.diag([0.01, 0.01, 0.2]), update_iterations=iterations)
        ids = [0, 1, 2]
        for i, m in zip(ids, ([3.0, 1.0, 0.4], [2.5, -1.5, 0.2], [4.0, 0.5, 0.9])):
            state.add_landmark(i, StaticPointBlock(), observe(state.pose, np.array(m)), 0.01 * np.eye(3))
        state.P = state.P + 1e-3 * np.eye(state.x.size)  # invertible prior, so the MAP cost is defined
        x_prior, P_prior = state.x.copy(), state.P.copy()
        truth = x_prior + rng.multivariate_normal(np.zeros(x_prior.size), P_prior, method="cholesky") \
            if iterations == 1 else truth
        zs = [observe(truth[:3], truth[3 + 3 * i:6 + 3 * i]) for i in ids]
        R = 0.0004 * np.eye(3)
        accepted, result = state.update_landmarks(ids, zs, R)
        assert accepted.all()
        results[iterations] = (np.linalg.norm(_map_cost_gradient(state, x_prior, P_prior, ids, zs, R)), result.nis)
    one, few, many = results[1], results[4], results[12]
    # σ_θ = 0.45 rad and points 2–4 m away: the single linearisation misses by centimetres, far
    # beyond R's 2 cm, so its gradient is large. Gauss–Newton from there converges,
    # at first slowly, far from the solution (here 3.4e3 → 3.7e2 after 4 iterations), then fast
    # (2e-7 after 12): require that it falls, and by ≥ 10³ at 12. The draw uses a Cholesky
    # factor, so it does not depend on the BLAS build (the default SVD route does).
    assert one[0] > 1.0
    assert many[0] < few[0] < one[0] and many[0] < 1e-3 * one[0]
    assert many[1] == one[1] == few[1]  # NIS of the first linearisation, for the gate


def _fd(f, x0, h=1e-6):
    return np.column_stack([(f(x0 + h * e) - f(x0 - h * e)) / (2 * h) for e in np.eye(x0.size)])


ARTICULATED = {
    "static": (get_model("static"), None),
    "prismatic": (get_model("prismatic"), None),
    "revolute": (get_model("revolute"), revolute_structure([0.3, -1.2, 0.8], [0.2, -1.0, 0.4], [1.0, 0.5, 0.0], 0.6)),
}


def _structure(name):
    from stslam.articulation.models import PrismaticStructure, StaticStructure
    if name == "static":
        return StaticStructure(p0=np.array([1.0, -2.0, 0.5]), residual_m=0.0)
    if name == "prismatic":
        d = np.array([0.3, -0.8, 0.52])
        return PrismaticStructure(p0=np.array([0.4, 0.1, 1.1]), direction=d / np.linalg.norm(d), residual_m=0.0)
    return ARTICULATED["revolute"][1]


@pytest.mark.parametrize("name", ["static", "prismatic", "revolute"])
def test_articulated_block_position_jacobian_and_initialisation(name):
    model = ARTICULATED[name][0]
    block = ArticulatedBlock(model, _structure(name), order=1, sigma_eta=0.01, sigma_rate0=0.5)
    x_b = np.array([0.73, -0.2])
    m, dm_dx = block.position(x_b)
    # Central differences (h = 1e-6) on smooth O(1) functions: error ≲ 1e-9.
    np.testing.assert_allclose(dm_dx, _fd(lambda v: block.position(v)[0], x_b), atol=1e-8)
    # A point on the curve initialises q exactly, and D = ∂q/∂m inverts ∂f/∂q there.
    x0, D, prior = block.initial(m)
    assert x0[0] == pytest.approx(0.73, abs=1e-12) and x0[1] == 0.0
    assert (D[:1] @ dm_dx[:, :1])[0, 0] == pytest.approx(1.0, abs=1e-12)
    np.testing.assert_allclose(prior, np.diag([0.0, 0.25]))
    F, Q = block.transition(1.0)
    np.testing.assert_allclose(F, [[1.0, 1.0], [0.0, 1.0]])
    np.testing.assert_allclose(Q, 1e-4 * np.array([[0.25, 0.5], [0.5, 1.0]]))  # B Bᵀ σ², B = (½, 1)


def test_constant_velocity_block_is_the_spec_recursion():
    # SPEC 6.2: m_t = m_{t−1} + (m_{t−1} − m_{t−2}) for δt = 1.
    block = ConstantVelocityPointBlock(sigma_acc=0.0, sigma_v0=0.1)
    F, _ = block.transition(1.0)
    m1, m2 = np.array([1.0, 2.0, 0.5]), np.array([1.3, 1.9, 0.5])
    nxt = F @ np.concatenate([m2, m2 - m1])
    np.testing.assert_allclose(nxt[:3], m2 + (m2 - m1), atol=1e-15)


def test_adding_a_landmark_propagates_robot_and_sensor_covariance():
    rng = np.random.default_rng(4)
    pose, P_pose = np.array([0.5, -0.3, 0.7]), 0.01 * _spd(rng, 3)
    state = SlamState(pose, P_pose)
    R = 0.0016 * np.eye(3)
    z = np.array([2.0, 0.4, 0.3])
    state.add_landmark("a", StaticPointBlock(), z, R)
    m, J_pose, J_z = point_from_observation(pose, z)
    np.testing.assert_allclose(state.x[3:], m, atol=ROUTES)
    np.testing.assert_allclose(state.P[3:, 3:], J_pose @ P_pose @ J_pose.T + J_z @ R @ J_z.T, atol=ROUTES)
    np.testing.assert_allclose(state.P[:3, 3:], P_pose @ J_pose.T, atol=ROUTES)
    # H of the landmark's own observation at the initial point reproduces z.
    z_hat, cols, H_cols = state.predict_observation("a")
    np.testing.assert_allclose(z_hat, z, atol=ROUTES)
    H_pose, H_m = observation_jacobians(pose, m)
    np.testing.assert_allclose(H_cols, np.hstack([H_pose, H_m]), atol=ROUTES)


def test_joint_update_equals_the_dense_update_of_stacked_observations():
    rng = np.random.default_rng(8)
    state = SlamState(np.array([0.2, 0.1, 0.4]), 0.02 * np.eye(3))
    R = 0.0016 * np.eye(3)
    for name, z in (("a", [2.0, 0.5, 0.2]), ("b", [1.5, -0.7, 0.1]), ("c", [3.0, 0.0, 0.4])):
        state.add_landmark(name, StaticPointBlock(), np.array(z), R)
    x0, P0 = state.x.copy(), state.P.copy()
    zs = np.array([[2.05, 0.47, 0.21], [3.02, 0.01, 0.38]])
    state.update_landmarks(["a", "c"], zs, R)
    H = np.zeros((6, x0.size))
    y = np.empty(6)
    for r, (name, z) in enumerate(zip(["a", "c"], zs)):
        idx = {"a": slice(3, 6), "c": slice(9, 12)}[name]
        m = x0[idx]
        H_pose, H_m = observation_jacobians(x0[:3], m)
        H[3 * r:3 * r + 3, :3], H[3 * r:3 * r + 3, idx] = H_pose, H_m
        y[3 * r:3 * r + 3] = z - observe(x0[:3], m)
    dense = ekf.update(x0, P0, y, H, np.kron(np.eye(2), R))
    np.testing.assert_allclose(state.x, dense.x, atol=ROUTES)
    np.testing.assert_allclose(state.P, dense.P, atol=ROUTES)


def test_gate_rejects_only_the_outlier():
    state = SlamState(np.zeros(3), 1e-4 * np.eye(3))
    R = 0.0016 * np.eye(3)
    state.add_landmark(0, StaticPointBlock(), np.array([2.0, 0.0, 0.1]), R)
    state.add_landmark(1, StaticPointBlock(), np.array([2.0, 1.0, 0.1]), R)
    accepted, result = state.update_landmarks([0, 1], np.array([[2.01, 0.0, 0.1], [2.6, 1.0, 0.1]]), R,
                                              max_nis=11.34)
    assert accepted.tolist() == [True, False] and result is not None
    # Per-landmark bounds: None switches the gate off for that observation.
    accepted, _ = state.update_landmarks([0, 1], np.array([[2.0, 0.0, 0.1], [2.6, 1.0, 0.1]]), R,
                                         max_nis=[11.34, None])
    assert accepted.tolist() == [True, True]


def test_batched_gate_nis_equals_the_per_observation_route():
    # The gate's NIS is computed for all of a frame's observations at once (issue 11); it must
    # equal the straightforward route, S = HPHᵀ + R per observation and yᵀS⁻¹y by Cholesky
    # (ekf.innovation_covariance_sparse + ekf.innovation_stats), with blocks of two sizes mixed.
    # Both are O(1)-conditioned 3×3 solves in float64: agreement to 1e-9 relative leaves 6 orders
    # of magnitude above round-off and is far below any gate decision's scale (χ²₃ bound 11.3).
    rng = np.random.default_rng(21)
    state = SlamState(np.array([0.3, -0.2, 0.5]), 0.01 * np.eye(3))
    R = 0.0016 * np.eye(3)
    structure = revolute_structure([2.0, 1.0, 0.0], [0, 0, 1], [1, 0, 0], 0.5)
    for i in range(6):
        state.add_landmark(i, StaticPointBlock(0.01), rng.uniform([1, -1, 0], [3, 1, 1]), R)
    state.add_landmark(6, ArticulatedBlock(get_model("revolute"), structure, 1, 0.1, 0.5),
                       observe(state.x[:3], structure.p0 + 0.5 * structure.v1), R)
    ids = list(range(7))
    Rs = np.stack([R * rng.uniform(0.5, 2.0) for _ in ids])
    zs = np.stack([state.predict_observation(i)[0] for i in ids]) + rng.normal(scale=0.05, size=(7, 3))
    batched = state.observation_nis(ids, zs, Rs)
    for j, i in enumerate(ids):
        z_hat, cols, H_cols = state.predict_observation(i)
        S, _ = ekf.innovation_covariance_sparse(state.P, cols, H_cols, Rs[j])
        np.testing.assert_allclose(batched[j], ekf.innovation_stats(zs[j] - z_hat, S)[0], rtol=1e-9)
    # And the gate built on it keeps the observations at or under the bound, rejects the rest.
    bound = float(np.median(batched))
    accepted, _ = state.update_landmarks(ids, zs, Rs, max_nis=bound)
    assert accepted.tolist() == (batched <= bound).tolist()


def test_remove_and_replace_keep_the_rest_of_the_covariance():
    rng = np.random.default_rng(2)
    state = SlamState(np.array([0.0, 0.0, 0.3]), 0.01 * _spd(rng, 3))
    R = 0.0016 * np.eye(3)
    for i, z in enumerate(([2.0, 0.5, 0.2], [1.5, -0.7, 0.1], [3.0, 0.0, 0.4])):
        state.add_landmark(i, StaticPointBlock(), np.array(z), R)
    P_before = state.P.copy()
    # Convert landmark 1 to a constant-velocity block: x_new = [m; 0] with J = [I; 0] and a velocity prior.
    J = np.vstack([np.eye(3), np.zeros((3, 3))])
    extra = np.diag([0, 0, 0, 0.01, 0.01, 0.01])
    state.replace_block(1, ConstantVelocityPointBlock(0.01, 0.1), J @ state.x[6:9], J, extra)
    keep = [0, 1, 2, 3, 4, 5, 9, 10, 11]
    np.testing.assert_allclose(state.P[:9, :9], P_before[np.ix_(keep, keep)], atol=ROUTES)
    np.testing.assert_allclose(state.P[9:12, 9:12], P_before[6:9, 6:9], atol=ROUTES)
    np.testing.assert_allclose(state.P[:9, 9:12], P_before[keep, 6:9], atol=ROUTES)
    np.testing.assert_allclose(state.P[12:, 12:], 0.01 * np.eye(3), atol=ROUTES)
    assert state.indices(2).tolist() == [6, 7, 8] and state.indices(1).tolist() == list(range(9, 15))
    state.remove_landmark(0)
    assert state.indices(2).tolist() == [3, 4, 5] and state.x.size == 12


def test_ten_thousand_oracle_steps_keep_P_symmetric_positive_semidefinite():
    # A long run of the oracle (all three block kinds) in square_centred with 16 static
    # landmarks (4 per side, to keep the test fast) and the robot circling for 10,000 frames. Symmetry is exact (P is symmetrised every step); the
    # smallest eigenvalue may dip below 0 only by round-off, ~1e-16 × the largest (≲ 1e-13).
    cfg = compose_config("dynamic_slam", ["world.n_frames=10000", "world.static_square.per_side=4"])
    world = world_from_config(cfg)
    run = simulate(world, sensor_from_config(cfg), np.random.default_rng(0))
    spec = make_filter("oracle", filter_params_from_config(cfg, "oracle"), world)
    worst = []

    def check(k, state):
        P = state.P
        assert np.array_equal(P, P.T), f"P not symmetric at frame {k}"
        eigenvalues = np.linalg.eigvalsh(P)
        worst.append(eigenvalues[0] / max(eigenvalues[-1], 1e-300))

    track = run_filter(spec, run, observer=check)
    assert len(worst) == 10000
    assert min(worst) > -1e-12
    assert np.all(np.isfinite(track.poses_xytheta))
    # Still tracking after 100 loops (a diverged filter drifts by metres): the median position
    # error stays at the 2 cm of a 110-frame run (measured 0.020 m; bound 2.5×), and the mean
    # pose NEES stays near its χ²₃ mean of 3 (measured 4.1: mildly overconfident with α's
    # large heading noise and frames that see a single landmark; bound 6 = twice the mean).
    errors = np.linalg.norm(track.poses_xytheta[:, :2] - world.poses_xytheta[:, :2], axis=1)
    assert np.median(errors) < 0.05
    assert np.mean(pose_nees(world.poses_xytheta, track.poses_xytheta, track.pose_covs)) < 6.0


@pytest.mark.parametrize("args, match", [
    (("kalman_slam", EkfSlamParams(0.01), None), r"^name: expected one of ekf_slam, dyn_slam, ekf_slam_gated, "
                                                 r"a_slam, a_slam_truth_onsets, oracle; got 'kalman_slam'$"),
    (("ekf_slam", EkfSlamParams(0.01), None, 3), r"^motion_order: expected 1 or 2, got 3$"),
    (("ekf_slam", EkfSlamParams(0.01), None, 2, 0), r"^iterations: expected an integer ≥ 1, got 0$"),
])
def test_make_filter_names_its_own_bad_argument(args, match):
    with pytest.raises(ValueError, match=match) as caught:
        make_filter(*args)
    assert not isinstance(caught.value, ConfigError)  # the config edge names filters.* and the top-level keys


def test_cached_predicted_observations_equal_fresh_ones_and_follow_the_state():
    # predict_observation keeps its answer until x is replaced: it must equal a fresh evaluation,
    # and a new x (here an update) must not see the old one.
    rng = np.random.default_rng(3)
    state = SlamState([0.1, -0.2, 0.3], 0.01 * np.eye(3))
    walk = StaticPointBlock(0.01)
    for i in range(4):
        state.add_landmark(i, walk, rng.normal(size=3) + [2.0, 0.0, 0.0], 0.01 * np.eye(3))
    for _ in range(2):
        for i in range(4):
            cached = state.predict_observation(i)
            assert state.predict_observation(i) is cached
            for a, b in zip(cached, state.predict_observation(i, state.x.copy()), strict=True):
                np.testing.assert_array_equal(a, b)
        state.update_landmarks([0, 2], rng.normal(size=(2, 3)) + [2.0, 0.0, 0.0], 0.01 * np.eye(3))
    trial = state.copy()
    trial.update_landmark(1, state.predict_observation(1)[0] + 0.01, 0.01 * np.eye(3))
    assert trial.predict_observation(1)[0] is not state.predict_observation(1)[0]
    assert not np.array_equal(trial.predict_observation(1)[0], state.predict_observation(1)[0])


def test_joint_update_noise_is_the_block_diagonal_of_the_observation_noises():
    from scipy.linalg import block_diag

    from stslam.slam.rows import block_diagonal
    rng = np.random.default_rng(4)
    Rs = np.stack([_spd(rng, 3) for _ in range(5)])
    np.testing.assert_array_equal(block_diagonal(Rs), block_diag(*Rs))


def test_shared_pose_terms_give_the_sensor_model_exactly():
    # The core evaluates R(θ) once per pose for all landmarks: the numbers must be those of
    # stslam.robot.sensor's observe and observation_jacobians, bit for bit.
    from stslam.robot.sensor import PoseObservation
    rng = np.random.default_rng(6)
    for _ in range(50):
        pose = np.array([*rng.normal(size=2), rng.uniform(-4, 4)])
        terms = PoseObservation(pose)
        for m in rng.normal(size=(5, 3)) * 3:
            z, H_pose = terms.observe(m)
            H_pose_ref, H_m_ref = observation_jacobians(pose, m)
            np.testing.assert_array_equal(z, observe(pose, m))
            np.testing.assert_array_equal(H_pose, H_pose_ref)
            np.testing.assert_array_equal(terms.H_m, H_m_ref)


def _rows_as_each_alone(state, asked) -> list:
    """predict_observations(asked), each row checked against predict_observation on a fresh copy of the state,
    bit for bit, and read-only; returns the rows."""
    together = state.predict_observations(asked)
    for i, row in zip(asked, together, strict=True):
        for got, expected in zip(row, state.copy().predict_observation(i), strict=True):
            np.testing.assert_array_equal(got, expected)
            assert not got.flags.writeable
    return together


def test_many_static_points_are_predicted_as_each_on_its_own_to_the_bit():
    """predict_observations computes the static points' rows together (PoseObservation.observe_many); the rows
    must be predict_observation's on a fresh state, bit for bit, for any mix with other blocks."""
    rng = np.random.default_rng(9)
    for trial in range(20):
        state = SlamState(np.array([*rng.normal(size=2), rng.uniform(-4, 4)]), 0.01 * np.eye(3))
        ids = list(range(12))
        for i in ids:
            block = (ConstantVelocityPointBlock(0.1, 0.5) if i % 5 == 2 else StaticPointBlock(0.01 * (i % 2)))
            state.add_landmark(i, block, rng.normal(size=3) * 3, 0.01 * np.eye(3))
        asked = list(rng.permutation(ids)[: rng.integers(1, 12)])
        together = _rows_as_each_alone(state, asked)
        assert state.predict_observation(asked[0]) is together[0]  # kept for the gate and the update alike


def test_articulated_and_moving_points_are_predicted_together_as_each_on_its_own_to_the_bit():
    """predict_observations computes the rows of blocks that share a stack_key together (blocks.stacked_positions:
    revolute, prismatic, with and without a slip; constant-velocity points); each row must be
    predict_observation's on a fresh state, bit for bit (else a filter's numbers move at round-off)."""
    from stslam.articulation.models import PrismaticStructure

    rng = np.random.default_rng(12)
    for trial in range(20):
        state = SlamState(np.array([*rng.normal(size=2), rng.uniform(-4, 4)]), 0.01 * np.eye(3))
        ids = list(range(16))
        for i in ids:
            slip = 0.1 * ((i // 4) % 2)
            if i % 4 == 0:
                axis = rng.normal(size=3)
                block = ArticulatedBlock(get_model("revolute"), revolute_structure(
                    rng.normal(size=3), axis, np.cross(axis, rng.normal(size=3)), rng.uniform(0.2, 1.0)),
                    1 + i % 3 // 2, 0.1, 0.2, slip)
            elif i % 4 == 1:
                direction = rng.normal(size=3)
                block = ArticulatedBlock(get_model("prismatic"), PrismaticStructure(
                    rng.normal(size=3), direction / np.linalg.norm(direction), 0.0), 1, 0.1, 0.2, slip)
            else:
                block = ConstantVelocityPointBlock(0.1, 0.5) if i % 4 == 2 else StaticPointBlock(0.01)
            state.add_landmark(i, block, rng.normal(size=3) * 3, 0.01 * np.eye(3))
        state.x = state.x + rng.normal(size=state.x.size)  # any q, slip and rate
        asked = list(rng.permutation(ids)[: rng.integers(2, 16)])
        together = _rows_as_each_alone(state, asked)
