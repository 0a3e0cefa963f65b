"""Robot motion model and point sensor (SPEC 5): Jacobians against finite differences, FOV, noise."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.errors import ConfigError
from stslam.robot.motion import (OMEGA_EPS, control_between, control_noise_cov, motion_control_hessians, motion_jacobians,
                          move, sample_noisy_controls, second_order_motion_noise)
from stslam.robot.sensor import (ConeFov, PinholeFov, observation_jacobians, observation_noise, observe,
                                 point_from_observation, pose_induced_variance, world_from_robot)

# Central differences with step 1e-6 on O(1) smooth functions have truncation error
# ~h² ≈ 1e-12 and round-off ~1e-16/h ≈ 1e-10; 1e-7 leaves margin for both.
FD_STEP = 1e-6
FD_TOL = 1e-7


def numerical_jacobian(f, x0):
    x0 = np.asarray(x0, dtype=float)
    columns = []
    for i in range(x0.size):
        step = np.zeros_like(x0)
        step[i] = FD_STEP
        columns.append((f(x0 + step) - f(x0 - step)) / (2 * FD_STEP))
    return np.column_stack(columns)


# Lopsided values: heading in the third quadrant, v and ω of different sign and size.
POSE = np.array([1.7, -0.4, 2.3])
ARC = np.array([0.37, -0.81])
STRAIGHT = np.array([-0.52, 0.0])


def test_arc_branch_moves_on_a_circle_about_the_turning_centre():
    # The centre of the arc is (x − (v/ω) sin θ, y + (v/ω) cos θ); both poses lie at |v/ω| from it
    # and the heading turns by ωδt (SPEC 5.1).
    dt = 1.3
    new = move(POSE, ARC, dt)
    ratio = ARC[0] / ARC[1]
    centre = POSE[:2] + ratio * np.array([-np.sin(POSE[2]), np.cos(POSE[2])])
    assert np.linalg.norm(new[:2] - centre) == pytest.approx(abs(ratio), abs=1e-12)
    assert np.linalg.norm(POSE[:2] - centre) == pytest.approx(abs(ratio), abs=1e-12)
    assert new[2] == pytest.approx(POSE[2] + ARC[1] * dt, abs=1e-15)


def test_straight_branch_and_its_continuity_with_the_arc():
    dt = 0.7
    new = move(POSE, STRAIGHT, dt)
    expected = POSE + np.array([STRAIGHT[0] * dt * np.cos(POSE[2]), STRAIGHT[0] * dt * np.sin(POSE[2]), 0.0])
    np.testing.assert_allclose(new, expected, atol=1e-15)
    # Just above ε the arc formula must agree with the straight line to O(ω δt²·v) ≈ 1e-8.
    nearly = move(POSE, STRAIGHT + np.array([0.0, 1e-8]), dt)
    np.testing.assert_allclose(nearly, expected, atol=1e-7)


@pytest.mark.parametrize("control", [ARC, STRAIGHT, np.array([2.1, 3.4]), np.array([0.05, -1e-3])],
                         ids=["arc", "straight", "fast-arc", "slow-arc"])
def test_motion_jacobians_match_finite_differences(control):
    dt = 0.9
    G, V = motion_jacobians(POSE, control, dt)
    if abs(control[1]) > OMEGA_EPS:
        G_fd = numerical_jacobian(lambda p: move(p, control, dt), POSE)
        V_fd = numerical_jacobian(lambda u: move(POSE, u, dt), control)
        np.testing.assert_allclose(G, G_fd, atol=FD_TOL)
        np.testing.assert_allclose(V, V_fd, atol=FD_TOL)
    else:
        # Straight branch: G by differences in the pose (ω stays 0); V's ω column is the
        # ω → 0 limit, checked against one-sided arc differences at ω = ±1e-4 (error O(ω) ≈ 1e-4).
        G_fd = numerical_jacobian(lambda p: move(p, control, dt), POSE)
        np.testing.assert_allclose(G, G_fd, atol=FD_TOL)
        v_col = numerical_jacobian(lambda v: move(POSE, [v[0], 0.0], dt), control[:1])
        np.testing.assert_allclose(V[:, :1], v_col, atol=FD_TOL)
        h = 1e-4
        w_col = (move(POSE, [control[0], h], dt) - move(POSE, [control[0], -h], dt)) / (2 * h)
        np.testing.assert_allclose(V[:, 1], w_col, atol=1e-6)


@pytest.mark.parametrize("control", [ARC, np.array([2.1, 3.4]), np.array([0.05, -1e-3])],
                         ids=["arc", "fast-arc", "slow-arc"])
def test_motion_control_hessians_match_differences_of_the_jacobian(control):
    dt = 0.9
    hess = motion_control_hessians(POSE, control, dt)
    for i in range(3):  # row i of V, differentiated in u: the Hessian of x'_i
        fd = numerical_jacobian(lambda u, i=i: motion_jacobians(POSE, u, dt)[1][i], control)
        # V's arc terms are O(v/ω²) and cancel, so differencing them with step h loses
        # ~1e-16·(|v|/ω²)/h to round-off (≈ 5e-6 at ω = 1e-3); ×10 margin, floor 1e-6.
        tol = max(1e-6, 10 * 1e-16 * abs(control[0]) / control[1] ** 2 / FD_STEP)
        np.testing.assert_allclose(hess[i], fd, atol=tol)
    np.testing.assert_allclose(hess, hess.transpose(0, 2, 1))


def test_motion_control_hessians_straight_branch_is_the_arc_limit():
    dt = 0.9
    straight = motion_control_hessians(POSE, STRAIGHT, dt)
    for w in (1e-4, -1e-4):
        # The arc formulas at |ω| = 1e-4 differ from the limit by O(ω) (≈ 1e-4) and lose ~1e-16/ω³
        # ≈ 1e-4 to cancellation; 1e-3 covers both.
        arc = motion_control_hessians(POSE, [STRAIGHT[0], w], dt)
        np.testing.assert_allclose(straight, arc, atol=1e-3)


def test_second_order_motion_noise_matches_monte_carlo():
    """The pose spread off V S Vᵀ's plane, where first order claims zero variance, is Q₂'s."""
    rng = np.random.default_rng(5)
    control, dt = np.array([0.21, 0.063]), 1.0
    S = control_noise_cov(control, [0.1, 0.05, 0.05, 0.1])  # the paper's α: σ_ω ≈ 81% of ω
    _, V = motion_jacobians(POSE, control, dt)
    normal = np.linalg.svd(V)[0][:, 2]  # the pose direction first order says never moves
    assert np.allclose(normal @ V @ S @ V.T @ normal, 0.0, atol=1e-15)
    draws = control + rng.multivariate_normal(np.zeros(2), S, size=200_000)
    poses = np.array([move(POSE, u, dt) for u in draws])
    spread = np.var(poses @ normal)
    predicted = normal @ second_order_motion_noise(POSE, control, S, dt) @ normal
    assert predicted > 0.0
    # Sample variance over 200,000 draws: relative SE ≈ √(κ/n) with kurtosis κ ≈ 9 for this
    # product-of-normals term, ≈ 0.7%; third- and higher-order terms are ~σ² ≈ 5% smaller; 10% covers both.
    assert spread == pytest.approx(predicted, rel=0.10)


def test_control_noise_covariance_and_sampling():
    alpha = [0.1, 0.05, 0.05, 0.1]
    S = control_noise_cov([0.2, -0.3], alpha)
    np.testing.assert_allclose(S, np.diag([0.1 * 0.04 + 0.05 * 0.09, 0.05 * 0.04 + 0.1 * 0.09]), atol=1e-15)
    u = np.tile([0.2, -0.3], (20000, 1))
    noisy = sample_noisy_controls(u, alpha, np.random.default_rng(5))
    # Sample variances of 20000 normals: relative standard error √(2/19999) ≈ 1%; 5% is 5 SE.
    np.testing.assert_allclose(np.var(noisy - u, axis=0), np.diag(S), rtol=0.05)
    # Sample means: standard error √(S_ii/20000); 5 SE.
    assert np.all(np.abs(np.mean(noisy - u, axis=0)) < 5 * np.sqrt(np.diag(S) / 20000))


def test_control_between_inverts_move_on_both_branches():
    for control in (ARC, STRAIGHT, np.array([0.2094, 0.0628])):
        recovered = control_between(POSE, move(POSE, control, 1.0), 1.0)
        np.testing.assert_allclose(recovered, control, atol=1e-12)


def test_bad_alpha_and_shapes_are_rejected():
    with pytest.raises(ValueError, match=r"^alpha: expected 4 numbers ≥ 0, got \[0.1, -0.2, 0.1, 0.1\]$") as caught:
        control_noise_cov([0.1, 0.1], [0.1, -0.2, 0.1, 0.1])
    assert not isinstance(caught.value, ConfigError)
    with pytest.raises(ValueError, match=r"pose_xytheta must have shape \(3,\)"):
        move([0.0, 1.0], ARC, 1.0)
    with pytest.raises(ValueError, match=r"control_vw must have shape \(2,\)"):
        motion_jacobians(POSE, [1.0, 2.0, 3.0], 1.0)


def test_observation_is_the_landmark_in_the_robot_frame():
    # Robot at (1, 2) facing +y (θ = π/2): a point 3 m ahead and 0.5 m up is at robot (3, 0, 0.5);
    # a point 1 m to the world's −x is on the robot's left (+y).
    pose = np.array([1.0, 2.0, np.pi / 2])
    z = observe(pose, np.array([[1.0, 5.0, 0.5], [0.0, 2.0, 0.0]]))
    np.testing.assert_allclose(z, [[3.0, 0.0, 0.5], [0.0, 1.0, 0.0]], atol=1e-15)


def test_observation_jacobians_match_finite_differences():
    m = np.array([-0.3, 2.9, 0.71])
    H_pose, H_m = observation_jacobians(POSE, m)
    np.testing.assert_allclose(H_pose, numerical_jacobian(lambda p: observe(p, m), POSE), atol=FD_TOL)
    np.testing.assert_allclose(H_m, numerical_jacobian(lambda q: observe(POSE, q), m), atol=FD_TOL)


def test_inverse_sensor_model_round_trip_and_jacobians():
    z = np.array([2.2, -0.6, 0.3])
    m, dm_dpose, dm_dz = point_from_observation(POSE, z)
    np.testing.assert_allclose(observe(POSE, m), z, atol=1e-14)
    np.testing.assert_allclose(dm_dpose, numerical_jacobian(lambda p: point_from_observation(p, z)[0], POSE),
                               atol=FD_TOL)
    np.testing.assert_allclose(dm_dz, numerical_jacobian(lambda q: point_from_observation(POSE, q)[0], z),
                               atol=FD_TOL)


def test_batched_inverse_sensor_model_takes_one_pose_or_one_per_observation():
    rng = np.random.default_rng(4)
    poses = np.column_stack([rng.uniform(-3, 3, (6, 2)), rng.uniform(-np.pi, np.pi, 6)])
    z = rng.normal(size=(6, 3))
    each = world_from_robot(poses, z)
    for k in range(6):
        np.testing.assert_allclose(each[k], point_from_observation(poses[k], z[k])[0], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(observe(POSE, world_from_robot(POSE, z)), z, atol=1e-14)
    with pytest.raises(ValueError, match=r"poses_xytheta must have shape \(3,\) or \(6, 3\), got \(2, 3\)"):
        world_from_robot(poses[:2], z)


def test_one_pose_inverse_sensor_model_gives_the_single_points_numbers_bit_for_bit():
    # A-SLAM maps a frame's points for selection in one call: each must be point_from_observation's R @ z + t
    # to the bit, or the selectors' inputs (and every decision after) would move at round-off.
    rng = np.random.default_rng(11)
    for _ in range(200):
        pose = rng.normal(size=3) * [3.0, 3.0, 2.0]
        z = rng.normal(size=(int(rng.integers(1, 40)), 3)) * 3.0
        np.testing.assert_array_equal(world_from_robot(pose, z), [point_from_observation(pose, p)[0] for p in z])


def test_observation_noise_is_sigma_times_standard_normals():
    noise = observation_noise(np.random.default_rng(9), 0.04, (4, 5, 3))
    np.testing.assert_array_equal(noise, 0.04 * np.random.default_rng(9).standard_normal((4, 5, 3)))


def test_cone_field_of_view_on_lopsided_points():
    fov = ConeFov(np.deg2rad(45.0), 4.0)
    points = np.array([
        [1.0, 0.99, 0.0],    # bearing 44.7°: in
        [1.0, 1.01, 0.0],    # bearing 45.3°: out
        [1.0, -0.99, 2.0],   # right side, high, range 2.45 m: in
        [3.9, 0.0, 1.0],     # range 4.03 m: out (3D range)
        [-1.0, 0.0, 0.0],    # behind: out
        [2.8, 2.7, 0.0],     # bearing 43.9°, range 3.89 m: in
    ])
    assert fov.contains(points).tolist() == [True, False, True, False, False, True]


def test_pinhole_field_of_view_on_lopsided_points():
    fov = PinholeFov(focal_px=300.0, width_px=320.0, height_px=240.0, min_depth_m=0.5, max_depth_m=4.0)
    # Horizontal limit |y|/x ≤ 160/300 = 0.5333 (28.07°), vertical |z|/x ≤ 120/300 = 0.4 (21.8°).
    points = np.array([
        [2.0, 1.06, 0.0],    # 0.530: in (to the left)
        [2.0, -1.07, 0.0],   # 0.535: out (to the right)
        [2.0, 0.0, 0.79],    # 0.395 up: in
        [2.0, 0.0, -0.81],   # 0.405 down: out
        [0.45, 0.0, 0.0],    # closer than 0.5 m: out
        [4.01, 0.0, 0.0],    # beyond 4 m: out
        [-2.0, 0.0, 0.0],    # behind: out
    ])
    assert fov.contains(points).tolist() == [True, False, True, False, False, False, False]
    u, v, _ = fov.pixels(np.array([[2.0, 0.5, 0.2]]))
    # Left of the robot is left in the image (u < 160) and up is up (v < 120).
    assert u[0] == pytest.approx(160 - 300 * 0.25) and v[0] == pytest.approx(120 - 300 * 0.1)


def test_pose_induced_variance_is_the_largest_eigenvalue_of_the_propagated_pose_covariance():
    # The batched route (A-SLAM's pose guard) against J P Jᵀ built per point from
    # point_from_observation's Jacobian; both are 3×3 float64 algebra on O(1) numbers, so they
    # agree to round-off (1e-12).
    rng = np.random.default_rng(5)
    pose = np.array([1.0, -0.5, 0.7])
    A = rng.normal(size=(3, 3))
    pose_cov = 0.01 * (A @ A.T) + 1e-4 * np.eye(3)
    zs = rng.uniform([-3, -3, 0], [3, 3, 2], size=(6, 3))
    batched = pose_induced_variance(pose, pose_cov, zs)
    for z, value in zip(zs, batched, strict=True):
        _, J, _ = point_from_observation(pose, z)
        assert abs(value - np.linalg.eigvalsh(J @ pose_cov @ J.T)[-1]) < 1e-12
    # A point at the robot: only the position uncertainty is left.
    assert abs(pose_induced_variance(pose, pose_cov, np.zeros((1, 3)))[0]
               - np.linalg.eigvalsh(pose_cov[:2, :2])[-1]) < 1e-12
