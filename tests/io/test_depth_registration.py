"""Depth registration into the colour camera: exact where it must be, geometric where it can be checked."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from stslam.geometry import pose_matrix
from stslam.io.depth_registration import register_depth
from stslam.robot.pinhole import intrinsics_matrix

K_COLOR = intrinsics_matrix(60.0, 60.0, 31.5, 23.5)  # 64 × 48


def _plane_depth(K_depth, size, T_color_depth, distance_m: float) -> np.ndarray:
    """Depth image of the depth camera looking at the plane z_c = distance_m of the colour camera."""
    w, h = size
    u, v = np.meshgrid(np.arange(w, dtype=float), np.arange(h, dtype=float))
    rays = np.stack([u, v, np.ones_like(u)], axis=-1) @ np.linalg.inv(K_depth).T  # z component 1
    R, t = T_color_depth[:3, :3], T_color_depth[:3, 3]
    # (R (s ray) + t)_z = distance  →  s = (distance − t_z) / (R ray)_z; the depth along z_d is s
    return (distance_m - t[2]) / (rays @ R[2])


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), low=st.floats(0.1, 2.0), spread=st.floats(0.0, 8.0))
def test_the_colour_camera_itself_gives_the_same_image(seed, low, spread):
    rng = np.random.default_rng(seed)
    image = rng.uniform(low, low + spread, size=(48, 64)).astype(np.float32)
    image[rng.random((48, 64)) < 0.1] = np.nan  # no return
    out = register_depth(image, K_COLOR, K_COLOR, np.eye(4), (64, 48))
    np.testing.assert_array_equal(out, image)  # one-to-one pixels, same depths, holes kept


@pytest.mark.parametrize("size,focal", [((80, 60), 75.0), ((32, 24), 30.0)])
def test_a_plane_seen_from_an_offset_depth_camera_lands_at_its_depth(size, focal):
    """Finer and coarser depth images, 2.5 cm to the side and turned 2°: the plane z_c = 2 m is 2 m in every
    covered colour pixel (to float32), and a coarser image leaves no holes inside the covered area."""
    w, h = size
    K_depth = intrinsics_matrix(focal, focal, (w - 1) / 2, (h - 1) / 2)
    T = pose_matrix(Rotation.from_euler("y", 2.0, degrees=True).as_matrix(), [0.025, 0.0, 0.0])
    out = register_depth(_plane_depth(K_depth, size, T, 2.0), K_depth, K_COLOR, T, (64, 48))
    covered = np.isfinite(out)
    inner = covered[4:-4, 4:-4]
    assert inner.mean() == 1.0  # the depth camera sees the colour camera's whole middle, the edges aside
    # A depth pixel's value is its centre's z_c on the plane: exactly 2 m up to float32 rounding.
    np.testing.assert_allclose(out[covered], 2.0, rtol=1e-6)


def test_the_nearer_surface_wins():
    """A box 1 m away in front of a wall 3 m away: where both land, the colour pixel gets 1 m."""
    K_depth = intrinsics_matrix(60.0, 60.0, 31.5, 23.5)
    T = pose_matrix(np.eye(3), [0.05, 0.0, 0.0])  # 5 cm baseline: the box's edge hides some wall
    depth = np.full((48, 64), 3.0)
    depth[16:32, 24:40] = 1.0
    out = register_depth(depth, K_depth, K_COLOR, T, (64, 48))
    # The box shifts by f·b/z = 60 · 0.05 / 1 = 3 px in the colour image, the wall by 1 px.
    assert np.all(out[16:32, 27:43] == 1.0)
    assert np.all(out[:, :10][np.isfinite(out[:, :10])] == 3.0)


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="register_depth: expected a 2-D depth image"):
        register_depth(np.ones(5), K_COLOR, K_COLOR, np.eye(4), (64, 48))
    with pytest.raises(ValueError, match="4 × 4 transform"):
        register_depth(np.ones((4, 4)), K_COLOR, K_COLOR, np.eye(3), (64, 48))


def test_a_depth_camera_much_coarser_than_colour_still_covers_it():
    """16 × 12 depth pixels over a 64 × 48 colour image (each footprint 4 × 4 colour pixels, and 12 × 12 for
    a camera 12 times coarser): the whole plane is covered, at its depth."""
    for scale in (4, 12):
        w, h = 64 // scale + (64 % scale > 0), 48 // scale + (48 % scale > 0)
        K_depth = intrinsics_matrix(60.0 / scale, 60.0 / scale, (w - 1) / 2, (h - 1) / 2)
        out = register_depth(np.full((h, w), 2.0), K_depth, K_COLOR, np.eye(4), (64, 48))
        assert np.isfinite(out[2:-2, 2:-2]).all() and np.all(out[np.isfinite(out)] == 2.0)
