"""Rotations, rigid transforms, planar poses, axis errors and depth noise (stslam.geometry)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stslam.geometry import (E_Z, axis_angle_deg, axis_line_distance, depth_noise_std, invert_pose,
                             cross3, pairwise_axis_angles_deg, pairwise_axis_line_distances,
                             planar_pose_from_matrix, planar_pose_matrix, pose_matrix, rotate_about_axis,
                             rotate_about_z, rotation_about_axis, rotation_z, rotation_z_derivative, skew,
                             transform_points)


def test_rotation_z_turns_counter_clockwise_seen_from_above():
    # Lopsided angles, so that a transposed matrix or a wrong sign shows.
    np.testing.assert_allclose(rotation_z(np.pi / 2) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(rotation_z(0.3) @ [2.0, 0.0, 5.0], [2 * np.cos(0.3), 2 * np.sin(0.3), 5.0])
    R = rotation_z(-1.1)
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-15)


def test_rotation_z_derivative_is_the_central_difference():
    theta, h = 0.7, 1e-6
    numeric = (rotation_z(theta + h) - rotation_z(theta - h)) / (2 * h)
    # central difference: error O(h²) ≈ 1e-12 plus round-off 1e-16/h ≈ 1e-10
    np.testing.assert_allclose(rotation_z_derivative(theta), numeric, atol=1e-9)


def test_rotate_about_z_is_rotation_z_per_angle():
    rng = np.random.default_rng(0)
    v = rng.normal(size=(50, 3))
    theta = rng.uniform(-np.pi, np.pi, 50)
    expected = np.array([rotation_z(t) @ x for t, x in zip(theta, v, strict=True)])
    np.testing.assert_allclose(rotate_about_z(v, theta), expected, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(rotate_about_z(v, 0.4), v @ rotation_z(0.4).T, rtol=1e-14, atol=1e-15)
    with pytest.raises(ValueError, match=r"vectors must have shape \(n, 3\), got \(3,\)"):
        rotate_about_z([1.0, 0.0, 0.0], 0.1)


def test_rodrigues_follows_the_right_hand_rule_and_agrees_with_scipy():
    rng = np.random.default_rng(1)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    angles = np.array([-2.5, -0.3, 0.0, 0.8, 3.0])
    for phi in angles:
        R = rotation_about_axis(axis, phi)
        np.testing.assert_allclose(R, Rotation.from_rotvec(phi * axis).as_matrix(), atol=1e-15)
        np.testing.assert_allclose(R @ axis, axis, atol=1e-15)  # the axis stays put
    # About z it is R(θ): e_x turns towards e_y.
    np.testing.assert_allclose(rotation_about_axis(E_Z, 0.9), rotation_z(0.9), atol=2e-16)
    # The vector form is the matrix form, angle by angle.
    v = rng.normal(size=3)
    np.testing.assert_allclose(rotate_about_axis(v, axis, angles),
                               [rotation_about_axis(axis, phi) @ v for phi in angles], atol=1e-15)
    np.testing.assert_array_equal(skew([1.0, 2.0, 3.0]) @ [4.0, 5.0, 6.0], np.cross([1, 2, 3], [4, 5, 6]))


def test_pose_inverse_round_trips_single_and_stacked():
    rng = np.random.default_rng(2)
    T = np.stack([pose_matrix(Rotation.random(random_state=i).as_matrix(), rng.normal(0.0, 3.0, 3))
                  for i in range(5)])
    np.testing.assert_allclose(invert_pose(T[0]) @ T[0], np.eye(4), atol=1e-14)
    stacked = invert_pose(T)
    for k in range(5):
        np.testing.assert_array_equal(stacked[k], invert_pose(T[k]))
        np.testing.assert_allclose(T[k] @ stacked[k], np.eye(4), atol=1e-14)
    points = rng.normal(size=(7, 3))
    np.testing.assert_allclose(transform_points(invert_pose(T[1]), transform_points(T[1], points)), points,
                               atol=1e-14)
    with pytest.raises(ValueError, match=r"T must have shape \(\.\.\., 4, 4\), got \(3, 3\)"):
        invert_pose(np.eye(3))


def test_planar_pose_round_trip_and_frame():
    pose = np.array([1.5, -0.4, 2.9])
    T = planar_pose_matrix(pose)
    np.testing.assert_allclose(planar_pose_from_matrix(T), pose, rtol=1e-15)
    np.testing.assert_allclose(T[:3, :3], rotation_z(pose[2]), atol=2e-16)
    # The base's x axis points along the heading; its origin is on the floor.
    np.testing.assert_allclose(transform_points(T, [1.0, 0.0, 0.0])[0],
                               [1.5 + np.cos(2.9), -0.4 + np.sin(2.9), 0.0], atol=1e-15)


def test_depth_noise_grows_with_the_square_of_depth():
    np.testing.assert_allclose(depth_noise_std([1.0, 2.0, 4.0], 1.5e-3), [1.5e-3, 6e-3, 2.4e-2], rtol=1e-15)


def test_axis_errors():
    assert axis_angle_deg([0, 0, 1], [0, 0, -3]) == pytest.approx(0.0, abs=1e-12)  # sign-blind
    assert axis_angle_deg([1, 0, 0], [1, 1, 0]) == pytest.approx(45.0)
    assert axis_angle_deg([0, 1, 0], [1, 0, 0]) == pytest.approx(90.0)
    tiny = 1e-9  # arccos would lose this angle entirely (cos = 1 − 5e-19)
    assert axis_angle_deg([1, 0, 0], [1, tiny, 0]) == pytest.approx(np.degrees(tiny), rel=1e-6)
    # skew lines: x-axis and a line along y through (0, 0, 2): distance 2
    assert axis_line_distance([0, 0, 0], [1, 0, 0], [5, -1, 2], [0, 3, 0]) == pytest.approx(2.0)
    # intersecting lines: 0
    assert axis_line_distance([0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]) == pytest.approx(0.0, abs=1e-15)
    # parallel (and anti-parallel) lines: distance between them, here √(3² + 4²)
    assert axis_line_distance([0, 0, 0], [0, 0, 1], [3, 4, 9], [0, 0, -2]) == pytest.approx(5.0)
    with pytest.raises(ValueError, match="non-zero"):
        axis_line_distance([0, 0, 0], [0, 0, 0], [1, 0, 0], [0, 1, 0])
    with pytest.raises(ValueError, match=r"a_hat: expected a finite vector of shape \(3,\)"):
        axis_angle_deg([1, 0], [1, 0, 0])


def test_pairwise_axis_errors_are_the_one_pair_floats():
    rng = np.random.default_rng(7)
    d1 = rng.standard_normal((9, 3)) * rng.lognormal(size=(9, 1))
    d2 = rng.standard_normal((6, 3))
    d2[:3] = d1[:3] * [[-2.0], [1.0], [0.5]]               # parallel and anti-parallel lines
    d2[3] = d1[3] + 1e-10 * rng.standard_normal(3)         # nearly parallel
    p1, p2 = rng.standard_normal((9, 3)), rng.standard_normal((6, 3))
    angles = np.array([[axis_angle_deg(a, b) for b in d2] for a in d1])
    distances = np.array([[axis_line_distance(p, a, q, b) for q, b in zip(p2, d2)] for p, a in zip(p1, d1)])
    np.testing.assert_array_equal(pairwise_axis_angles_deg(d1, d2), angles)
    np.testing.assert_array_equal(pairwise_axis_line_distances(p1, d1, p2, d2), distances)
    with pytest.raises(ValueError, match="non-zero"):
        pairwise_axis_angles_deg(d1, np.zeros((1, 3)))
    with pytest.raises(ValueError, match="non-zero"):
        pairwise_axis_line_distances(p1, d1, p2[:1], np.zeros((1, 3)))
    with pytest.raises(ValueError, match=r"p1: expected finite vectors of shape \(n, 3\)"):
        pairwise_axis_line_distances(np.full((1, 3), np.nan), d1[:1], p2, d2)


def test_axis_errors_are_the_floats_of_the_numpy_formulas():
    rng = np.random.default_rng(9)
    for case in range(300):
        d1, d2, p1, p2 = rng.standard_normal((4, 3)) * rng.lognormal(size=(4, 1))
        if case % 3 == 0:
            d2 = d1 * rng.choice([-2.0, 0.5])  # parallel lines
        c = np.cross(d1, d2)
        angle = float(np.degrees(np.arctan2(np.linalg.norm(c), abs(float(d1 @ d2)))))
        if np.linalg.norm(c) <= 1e-12 * np.linalg.norm(d1) * np.linalg.norm(d2):
            distance = float(np.linalg.norm(np.cross(p2 - p1, d1)) / np.linalg.norm(d1))
        else:
            distance = float(abs((p2 - p1) @ c) / np.linalg.norm(c))
        assert axis_angle_deg(d1, d2) == angle
        assert axis_line_distance(p1, d1, p2, d2) == distance


def test_cross3_is_np_cross():
    rng = np.random.default_rng(10)
    for _ in range(200):
        a, b = rng.standard_normal((2, 3)) * rng.lognormal(size=(2, 1))
        np.testing.assert_array_equal(cross3(a, b), np.cross(a, b))
    np.testing.assert_array_equal(np.signbit(cross3([1.0, 0.0, 0.0], [2.0, 0.0, 0.0])), np.signbit(np.cross([1.0, 0, 0], [2.0, 0, 0])))
