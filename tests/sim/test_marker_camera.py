"""Realistic marker tracks: a camera-marker tracker's errors and hand-driven furniture (SPEC 10)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.selection.nested_price import curvature_estimate
from stslam.sim.marker_camera import MarkerCamera, observe_markers
from stslam.sim.track_generator import REALISTIC_KINDS, TRUE_MODEL, generate_track, generate_tracks


def test_realistic_set_covers_the_kinds_with_quaternions_and_ground_truth():
    tracks = generate_tracks(12, 0, camera=MarkerCamera())
    assert {t.kind for t in tracks} == set(REALISTIC_KINDS)
    for t in tracks:
        assert t.orientations_xyzw.shape == (t.points_world.shape[0], 4)
        assert np.allclose(np.linalg.norm(t.orientations_xyzw, axis=1), 1.0)
        assert np.all(np.diff(t.times_s) > 0) and t.true_model == TRUE_MODEL[t.kind]
        assert {"camera_bias", "camera_distance_m"} <= set(t.metadata())
        assert np.linalg.norm(t.axis_direction) == pytest.approx(1.0)


def test_noise_grows_with_depth_and_outliers_jumps_dropouts_occur():
    still = np.zeros((3000, 3))
    times = np.arange(3000) / 30.0
    spread = []
    for distance in [(1.0, 1.0), (3.0, 3.0)]:
        camera = MarkerCamera(distance_m=distance, bias_scale=(0.0, 0.0), bias_radial=(0.0, 0.0), outlier_rate=0.0,
                              jump_rate=0.0, dropout_rate=0.0, sigma0_m=(0.001, 0.001), depth_coeff=(0.002, 0.002))
        observed, *_ = observe_markers(np.random.default_rng(1), still, times, camera)
        spread.append(np.linalg.norm(observed - observed.mean(axis=0), axis=1).mean())
    assert spread[1] > 2.5 * spread[0]
    observed, kept_times, kept, _, _ = observe_markers(np.random.default_rng(2), still, times, MarkerCamera())
    assert kept_times.size < times.size  # dropouts (about 10 bursts of 0.1–1 s in 100 s)
    offsets = np.linalg.norm(observed - np.median(observed, axis=0), axis=1)
    assert np.sum(offsets > 0.02) >= 5  # outliers and jumps, centimetres off


def test_the_depth_bias_bends_a_straight_slide():
    # A 0.6 m slide across the image at 1 m, β₂ = 0.3: bent with curvature ≈ 2β₂/z.
    x = np.linspace(-0.3, 0.3, 200)
    camera = MarkerCamera(distance_m=(1.0, 1.0), bias_radial=(0.3, 0.3), bias_scale=(0.0, 0.0), outlier_rate=0.0,
                          jump_rate=0.0, dropout_rate=0.0, sigma0_m=(0.0002, 0.0002), depth_coeff=(0.0, 0.0))
    for seed in range(3):
        rng = np.random.default_rng(seed)
        slide = np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])
        observed, *_ = observe_markers(rng, slide, np.arange(200) / 30.0, camera)
        kappa, _, _ = curvature_estimate(observed, 0.0002)
        assert 0.2 < np.linalg.norm(kappa) < 0.9  # a circle of radius 1–5 m fits better than the line


def test_realistic_motion_has_long_rests_slow_pushes_small_and_large_radii_and_long_slides():
    tracks = [generate_track(np.random.default_rng(s), k, camera=MarkerCamera())
              for s in range(40) for k in ("door", "cabinet_door", "sliding_door")]
    radii = [t.radius_m for t in tracks if t.kind != "sliding_door"]
    assert min(radii) < 0.3 and max(radii) > 0.9
    assert max(t.onset_s for t in tracks) > 3.0
    travel = [np.ptp(t.points_world @ t.axis_direction) for t in tracks if t.kind == "sliding_door"]
    assert max(travel) > 0.6
    dishwasher = generate_track(np.random.default_rng(0), "dishwasher", camera=MarkerCamera())
    assert dishwasher.true_model == "revolute"  # horizontal hinge, seen from a camera frame
