"""Renderer, depth sensor model, door kinematics and robot path of the fridge sequence (SPEC 9)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from stslam.rgbd.sequence import FridgeSequence, SequenceConfig, door_angle_profile
from stslam.geometry import invert_pose, pose_matrix, transform_points
from stslam.robot.pinhole import back_project_pixels, project_points
from stslam.rgbd.renderer import PinholeImage, render_view, sensor_depth, texture_pyramid
from stslam.robot.motion import control_between
from stslam.rgbd.scene import DOOR_LABELS, LABEL_DOOR_FRONT, TexturedQuad, door_quads_at, fridge_room

SMALL = SequenceConfig(n_frames=40, width=160, height=120)


@pytest.fixture(scope="module")
def small_sequence():
    return FridgeSequence(SMALL, seed=5)


def _camera_looking_north(position_world):
    """T_world_camera of a camera at ``position_world`` looking along world +y, image x along world +x."""
    R_world_camera = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    return pose_matrix(R_world_camera, position_world)


def _plane_quad(rng):
    # A 4 m × 3 m wall at y = 2.5 m, tilted 30° about z so depth varies across the image.
    angle = np.deg2rad(30.0)
    edge_u = 4.0 * np.array([np.cos(angle), np.sin(angle), 0.0])
    corner = np.array([0.0, 2.5, 2.5]) - 0.5 * edge_u
    texture = rng.integers(0, 255, size=(60, 80, 3), dtype=np.uint8)
    return TexturedQuad(corner, edge_u, np.array([0.0, 0.0, -3.0]), texture=0, label=7), texture


def test_rendered_depth_of_a_plane_matches_ray_plane_intersection():
    rng = np.random.default_rng(0)
    quad, texture = _plane_quad(rng)
    K = np.array([[120.0, 0.0, 79.5], [0.0, 110.0, 59.5], [0.0, 0.0, 1.0]])
    camera = PinholeImage.from_intrinsics(K, 160, 120)
    T_world_camera = _camera_looking_north([0.3, 0.0, 1.1])
    view = render_view([quad], [texture_pyramid(texture)], camera, T_world_camera)
    covered = view.label == 7
    assert covered.mean() > 0.5  # the wall fills most of the view

    # Independent route: each pixel's world ray r = R K⁻¹ (u, v, 1) from C meets n·(X − P0) = 0 at
    # s = n·(P0 − C) / n·r, and the optical-axis depth of C + s r is s.
    v, u = np.nonzero(covered)
    rays_camera = np.column_stack([(u - K[0, 2]) / K[0, 0], (v - K[1, 2]) / K[1, 1], np.ones(u.size)])
    rays_world = rays_camera @ T_world_camera[:3, :3].T
    n = quad.normal_world
    s = (n @ (quad.corner_world - T_world_camera[:3, 3])) / (rays_world @ n)
    # float32 z-buffer: relative error of a few float32 ulps (1.2e-7 each).
    np.testing.assert_allclose(view.depth_m[covered], s, rtol=2e-6)


def test_back_projected_door_pixels_lie_on_the_door_front(small_sequence):
    """K and T_world_camera (the conventions the front end relies on) put each door pixel on the door."""
    seq = small_sequence
    k = 15
    angle = float(seq.door_angles_rad[k])
    assert angle > 0.3  # the door is well open in this frame
    T_world_camera = seq.T_world_camera(k)
    view = seq.render(k)
    v, u = np.nonzero(view.label == LABEL_DOOR_FRONT)
    assert u.size > 500
    points_world = transform_points(T_world_camera, back_project_pixels(seq.K, np.column_stack([u, v]),
                                                                        view.depth_m[v, u]))
    front = door_quads_at(seq.room.door_closed_quads, seq.hinge_point_world, seq.hinge_axis_world, angle)[0]
    assert front.label == LABEL_DOOR_FRONT
    offset = points_world - front.corner_world
    # On the plane: float32 depth at ≤ 3 m is exact to ~0.3 µm; allow 10 µm.
    np.testing.assert_allclose(offset @ front.normal_world, 0.0, atol=1e-5)
    # Inside the panel: edge coordinates in [0, 1] (a pixel's centre may sit half a pixel outside).
    for edge in (front.edge_u_world, front.edge_v_world):
        a = offset @ edge / (edge @ edge)
        assert a.min() > -0.01 and a.max() < 1.01
    # And the door's free top corner projects into the image where the door is drawn.
    uv, z = project_points(seq.K, transform_points(invert_pose(T_world_camera), front.corner_world))
    assert z[0] > 0
    col, row = np.round(uv[0]).astype(int)
    window = view.label[max(0, row - 2):row + 3, max(0, col - 2):col + 3]
    assert np.isin(window, DOOR_LABELS).any()


def test_depth_noise_std_follows_c_z_squared(small_sequence):
    """Noisy minus noise-free depth, binned by depth, has std 1.5e-3 z² (SPEC 9)."""
    seq = small_sequence
    clean = FridgeSequence(replace(SMALL, depth_noise_coefficient=0.0), seed=5)
    errors, depths = [], []
    for k in range(0, 40, 4):
        noisy, exact = seq.frame(k).depth_m, clean.frame(k).depth_m
        valid = np.isfinite(noisy)
        np.testing.assert_array_equal(valid, np.isfinite(exact))  # noise never makes or fills a hole
        errors.append((noisy - exact)[valid])
        depths.append(exact[valid])
    errors, depths = np.concatenate(errors), np.concatenate(depths)
    edges = np.arange(1.0, 4.01, 0.5)
    checked = 0
    for lo, hi in zip(edges[:-1], edges[1:]):
        inside = (depths >= lo) & (depths < hi)
        n = int(inside.sum())
        if n < 2000:
            continue
        ratio = np.std(errors[inside] / (1.5e-3 * depths[inside] ** 2))
        # std of a sample std of n normals ≈ 1/√(2n) ≤ 1.6 %: 5 of them, plus float32 rounding of
        # z (≤ 3e-7 m, under 0.1 % of σ_z ≥ 1.5 mm).
        assert abs(ratio - 1.0) < 5.0 / np.sqrt(2 * n)
        checked += 1
    assert checked >= 3


def test_holes_beyond_range_and_at_grazing_angles():
    rng = np.random.default_rng(1)
    depth = np.array([[0.2, 1.0, 3.9, 4.1, np.inf]], dtype=np.float32)
    cos = np.ones_like(depth)
    out = sensor_depth(depth, cos, rng)
    assert np.isnan(out[0, [0, 3, 4]]).all() and np.isfinite(out[0, [1, 2]]).all()
    grazing = sensor_depth(np.full((1, 3), 2.0, np.float32),
                           np.cos(np.deg2rad([[10.0, 74.0, 76.0]])).astype(np.float32), rng)
    assert np.isfinite(grazing[0, :2]).all() and np.isnan(grazing[0, 2])


def test_door_turns_about_its_hinge_towards_the_room():
    room = fridge_room(np.random.default_rng(2))
    closed = room.door_closed_quads
    opened = door_quads_at(closed, room.hinge_point_world, room.hinge_axis_world, np.pi / 2)
    # Every door point's distance to the hinge axis is unchanged (a rotation about it).
    p, a = room.hinge_point_world, room.hinge_axis_world
    for q0, q1 in zip(closed, opened):
        for x0, x1 in [(q0.corner_world, q1.corner_world),
                       (q0.corner_world + q0.edge_u_world, q1.corner_world + q1.edge_u_world)]:
            d0, d1 = x0 - p, x1 - p
            assert np.isclose(np.linalg.norm(d0 - (d0 @ a) * a), np.linalg.norm(d1 - (d1 @ a) * a))
    # Closed front faces the room (−y); opened by 90° it faces +x; the free edge swings to −y.
    np.testing.assert_allclose(closed[0].normal_world, [0.0, -1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(opened[0].normal_world, [1.0, 0.0, 0.0], atol=1e-12)
    free_edge = opened[0].corner_world  # top-left seen from the front = the free edge
    assert free_edge[1] < room.hinge_point_world[1] - 0.7


def test_door_profile_closed_open_closed():
    tau = np.linspace(0.0, 1.0, 101)
    angle = door_angle_profile(tau, 1.5, (0.15, 0.4, 0.6, 0.85))
    assert np.all(angle[tau <= 0.15] == 0.0) and np.all(angle[tau >= 0.85] == 0.0)
    np.testing.assert_allclose(angle[(tau >= 0.4) & (tau <= 0.6)], 1.5)
    assert np.all(np.diff(angle[(tau > 0.15) & (tau < 0.4)]) > 0)


def test_odometry_is_the_alpha_model_and_ground_truth_follows_the_motion_model(small_sequence):
    seq = small_sequence
    dt = 1.0 / SMALL.rate_hz
    # Ground truth re-integrates the true controls exactly (SPEC 5.1).
    for k in range(len(seq) - 1):
        np.testing.assert_allclose(control_between(seq.poses_gt_xytheta[k], seq.poses_gt_xytheta[k + 1], dt),
                                   seq.controls_gt_vw[k], atol=1e-9)
    # û − u standardised by S(u) = diag(α1 v² + α2 ω², α3 v² + α4 ω²) is N(0, 1): with 39 draws per
    # component the sample std is 1 ± 0.11 (1/√78); 0.4 is > 3.5 of those.
    a = np.array(SMALL.alpha)
    u = seq.controls_gt_vw
    std = np.sqrt(np.column_stack([a[0] * u[:, 0] ** 2 + a[1] * u[:, 1] ** 2,
                                   a[2] * u[:, 0] ** 2 + a[3] * u[:, 1] ** 2]))
    z = (seq.controls_odom_vw - u) / std
    assert np.all(np.abs(np.std(z, axis=0) - 1.0) < 0.4)


def test_the_fridge_door_is_in_view_in_every_frame(small_sequence):
    seq = small_sequence
    for k in range(0, len(seq), 3):
        view = seq.render(k)
        assert np.isin(view.label, DOOR_LABELS).mean() > 0.05, k


def test_same_seed_same_frame_other_seed_other_textures():
    a = FridgeSequence(SequenceConfig(n_frames=2, width=64, height=48), seed=9).frame(1)
    b = FridgeSequence(SequenceConfig(n_frames=2, width=64, height=48), seed=9).frame(1)
    c = FridgeSequence(SequenceConfig(n_frames=2, width=64, height=48), seed=10).frame(1)
    assert np.array_equal(a.rgb, b.rgb) and np.array_equal(a.depth_m, b.depth_m, equal_nan=True)
    assert not np.array_equal(a.rgb, c.rgb)
