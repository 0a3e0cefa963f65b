"""The RGB-D front end (SPEC 8.5, 9): back-projection, depth lookup, LK tracking, tracks of a generated sequence."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from stslam.rgbd.sequence import FridgeSequence, SequenceConfig
from stslam.io.mcap_write import write_fridge_mcap
from stslam.rgbd.frontend import (FeatureTracker, TrackerSettings, back_project_with_covariance, detect_bucketed,
                                   lookup_depth, nan_median_range, track_forward_backward)
from stslam.robot.pinhole import intrinsics_matrix, project_points
from stslam.rgbd.tracks import collect_tracks, world_points

K = intrinsics_matrix(200.0, 210.0, 79.5, 59.5)
SHORT = SequenceConfig(n_frames=40, width=160, height=120)


@pytest.fixture(scope="module")
def short_sequence(tmp_path_factory):
    """Tracks of a 40-frame 160 × 120 generated sequence (seed 11)."""
    path = tmp_path_factory.mktemp("fridge") / "short.mcap"
    write_fridge_mcap(path, FridgeSequence(SHORT, 11))
    return collect_tracks(path, TrackerSettings(target_tracks=80))


def textured(rng, shape=(120, 160)) -> np.ndarray:
    """A smooth random texture (uint8) with corners: blocks of random grey levels."""
    blocks = rng.integers(0, 256, size=(shape[0] // 8 + 2, shape[1] // 8 + 2)).astype(np.uint8)
    return np.kron(blocks, np.ones((8, 8), dtype=np.uint8))[:shape[0], :shape[1]]


def test_back_projection_round_trip_and_covariance():
    rng = np.random.default_rng(0)
    uv = rng.uniform([0, 0], [160, 120], size=(20, 2))
    z = rng.uniform(0.5, 4.0, size=20)
    points, covs = back_project_with_covariance(K, uv, z, 1.0, 1.5e-3)
    uv_back, z_back = project_points(K, points)
    np.testing.assert_allclose(uv_back, uv, atol=1e-9)  # exact inverse up to rounding
    np.testing.assert_allclose(z_back, z, atol=1e-12)
    # At the principal point the covariance is diagonal: (σ z/fx)², (σ z/fy)², (c z²)².
    _, cov = back_project_with_covariance(K, [[79.5, 59.5]], [2.0], 1.0, 1.5e-3)
    np.testing.assert_allclose(cov[0], np.diag([(2 / 200) ** 2, (2 / 210) ** 2, (1.5e-3 * 4) ** 2]), atol=1e-15)
    # Covariances are symmetric positive definite.
    assert np.all(np.linalg.eigvalsh(covs) > 0)


def test_lookup_depth_rejects_holes_edges_range_and_borders():
    s = TrackerSettings(depth_half_window_px=2, max_depth_spread_m=0.08, depth_min_m=0.3, depth_max_m=4.0)
    depth = np.full((40, 40), 2.0, dtype=np.float32)
    depth[:, 20:] = 3.0          # a depth edge at column 20
    depth[30:, :10] = np.nan     # a hole
    depth[:5, 30:] = 5.0         # beyond range
    pixels = np.array([[5, 5], [20, 10], [5, 35], [35, 2], [0, 0], [12, 12]], dtype=float)
    z, ok = lookup_depth(depth, pixels, s)
    # (5,5) flat: 2 m; (20,10) straddles the edge; (5,35) in the hole; (35,2) beyond range;
    # (0,0) corner: 9 of 25 pixels inside, fewer than half; (12,12) flat.
    assert ok.tolist() == [True, False, False, False, False, True]
    np.testing.assert_array_equal(z[ok], [2.0, 2.0])
    assert np.all(np.isnan(z[~ok]))


def test_lk_recovers_a_shift_and_the_forward_backward_check_rejects_noise():
    rng = np.random.default_rng(1)
    big = textured(rng, (140, 180))
    a = np.ascontiguousarray(big[10:130, 10:170])
    b = np.ascontiguousarray(big[8:128, 7:167])  # content moves by (+3, +2) pixels
    s = TrackerSettings()
    corners = detect_bucketed(a, np.empty((0, 2)), s)
    assert corners.shape[0] >= 20
    inner = corners[(corners[:, 0] > 15) & (corners[:, 0] < 140) & (corners[:, 1] > 15) & (corners[:, 1] < 100)]
    moved, ok = track_forward_backward(a, b, inner, s)
    assert ok.mean() > 0.9
    # Block-texture corners are sharp: LK should be sub-pixel; 0.2 px leaves room for its 0.03 px stop rule × levels.
    np.testing.assert_allclose(moved[ok] - inner[ok], np.tile([3.0, 2.0], (ok.sum(), 1)), atol=0.2)
    noise = rng.integers(0, 256, size=a.shape).astype(np.uint8)
    _, ok_noise = track_forward_backward(a, noise, inner, s)
    assert ok_noise.mean() < 0.5  # an unrelated image: most tracks fail the forward–backward check


def test_bucketed_detection_spreads_corners_over_the_image():
    rng = np.random.default_rng(2)
    grey = np.full((120, 160), 128, dtype=np.uint8)
    grey[:60, :80] = textured(rng)[:60, :80]                # rich texture in one quadrant
    grey[60:, 80:] = (textured(rng)[60:, 80:] // 8 + 100)    # weak texture elsewhere
    corners = detect_bucketed(grey, np.empty((0, 2)), TrackerSettings(target_tracks=40, grid_cols=2, grid_rows=2))
    in_weak = (corners[:, 0] >= 80) & (corners[:, 1] >= 60)
    assert in_weak.sum() >= 5  # the weak quadrant still gets its share (10), not crowded out


def test_static_points_stay_put_in_the_world(short_sequence):
    """Tracks of static surfaces, mapped with the true poses, scatter as their covariances say."""
    tracks = short_sequence
    nis = []
    for i, n in tracks.track_lengths().items():
        if n < 20:
            continue
        ks, z, covs = tracks.track_robot(i)
        points = world_points(tracks.poses_gt_xytheta, ks, z)
        if np.linalg.norm(points - np.median(points, axis=0), axis=1).max() > 0.1:
            continue  # a door point (moves by decimetres) or one that slid along an edge
        centre = points.mean(axis=0)
        theta = tracks.poses_gt_xytheta[ks, 2]
        for p, c, t in zip(points, covs, theta):
            Rz = np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1]])
            e = p - centre
            nis.append(e @ np.linalg.solve(Rz @ c @ Rz.T, e))
    assert len(nis) > 200
    # χ²₃ has median 2.37; LK's pixel noise is below the assumed 1 px, so the median sits lower,
    # and bounded above: 2.37 × 3 would flag a covariance three times too small.
    assert np.median(nis) < 3 * 2.37


def test_tracker_keeps_ids_and_restarts_on_a_size_change():
    rng = np.random.default_rng(3)
    img = textured(rng)
    rgb = np.repeat(img[:, :, None], 3, axis=2)
    depth = np.full(img.shape, 2.0, dtype=np.float32)
    tracker = FeatureTracker(TrackerSettings(target_tracks=30))
    first = tracker.step(rgb, depth, K)
    second = tracker.step(rgb, depth, K)
    assert first.track_ids.size > 10
    assert set(first.track_ids.tolist()) == set(second.track_ids.tolist())  # identical image: all survive
    small = tracker.step(rgb[:60, :80], depth[:60, :80], K)
    assert min(small.track_ids) >= tracker.n_started - small.n_live  # fresh ids only


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 30), st.integers(1, 49), st.floats(0.0, 0.9), st.booleans())
def test_nan_median_range_is_numpys_nanmedian_nanmin_and_nanmax_to_the_bit(seed, n, m, holes, ties):
    # depth windows: float32 depths in float64, NaN holes, each row with at least one depth; ties (depths
    # rounded to 1 cm) exercise equal middle values. Bit equality, since lookup_depth's z must not change.
    rng = np.random.default_rng(seed)
    rows = rng.uniform(0.3, 4.0, size=(n, m)).astype(np.float32).astype(float)
    if ties:
        rows = np.round(rows, 2)
    rows[rng.random((n, m)) < holes] = np.nan
    rows[:, 0] = np.where(np.isnan(rows).all(axis=1), 1.0, rows[:, 0])
    n_valid = np.sum(np.isfinite(rows), axis=1)
    median, low, high = nan_median_range(rows, n_valid)
    np.testing.assert_array_equal(median, np.nanmedian(rows, axis=1))
    np.testing.assert_array_equal(low, np.nanmin(rows, axis=1))
    np.testing.assert_array_equal(high, np.nanmax(rows, axis=1))
