"""Selection with each observation's own covariance (SPEC 13): the pose's share weighs against motion."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.articulation.evidence import motion_p_value, weighted_motion_p_value
from stslam.selection.observation_covariance import ObservationCovariances
from stslam.selection.selector import ModelSelector

from test_selection import paper_settings, prismatic_track, revolute_track, static_track

SIGMA = 0.04


def test_weighted_motion_test_with_isotropic_covariances_is_the_plain_test():
    rng = np.random.default_rng(0)
    t = np.arange(25) * 0.5
    for speed in (0.0, 0.004, 0.05):
        points = rng.normal(0.0, SIGMA, (25, 3)) + np.outer(t * speed, [0.6, 0.8, 0.0])
        covs = np.repeat((SIGMA ** 2 * np.eye(3))[None], 25, axis=0)
        assert weighted_motion_p_value(points, t, covs, 0.01 ** 2) == pytest.approx(
            motion_p_value(points, t, SIGMA ** 2 + 0.01 ** 2), rel=1e-9, abs=1e-300)


@pytest.mark.parametrize("track", [static_track, prismatic_track, revolute_track])
def test_covariance_sigma_squared_identity_is_the_selector_without_one(track):
    # σ_z² I given with every point is what the selector assumes without one: the same μ
    # (up to round-off: the filters then step one by one instead of as a bank).
    points = track(40, SIGMA, np.random.default_rng(1))
    plain, given = ModelSelector(paper_settings()), ModelSelector(paper_settings())
    for z in points:
        mu_plain, mu_given = plain.observe(z), given.observe(z, cov=SIGMA ** 2 * np.eye(3))
        if mu_plain is None:
            assert mu_given is None
        else:
            np.testing.assert_allclose(mu_given, mu_plain, rtol=1e-6, atol=1e-12)
    assert given.held_model == plain.held_model
    assert given.motion_p_value() == pytest.approx(plain.motion_p_value(), rel=1e-6)


def test_a_static_point_seen_through_a_wandering_pose_moves_only_without_its_covariance():
    # The world point inherits a pose error of 0.15 m std along x: read against σ_z alone it
    # has moved; against its own covariance (σ_z² I + the pose's share) it has not.
    rng = np.random.default_rng(2)
    n, pose_sigma = 60, 0.15
    wander = rng.normal(0.0, pose_sigma, (n, 1)) * np.array([1.0, 0.0, 0.0])
    points = static_track(n, SIGMA, rng) + wander
    cov = SIGMA ** 2 * np.eye(3) + np.diag([pose_sigma ** 2, 0.0, 0.0])
    plain, given = ModelSelector(paper_settings()), ModelSelector(paper_settings())
    for z in points:
        plain.observe(z)
        given.observe(z, cov=cov)
    assert plain.motion_p_value() < 1e-3
    assert given.motion_p_value() > 0.05


def test_a_mover_still_moves_against_a_modest_pose_share():
    points = prismatic_track(40, SIGMA, np.random.default_rng(3))
    selector = ModelSelector(paper_settings())
    for z in points:
        selector.observe(z, cov=(SIGMA ** 2 + 0.05 ** 2) * np.eye(3))
    assert selector.motion_p_value() < 1e-6
    assert selector.held_model == "prismatic"


def test_covariances_are_checked_and_fill_earlier_points_with_sigma_squared():
    covs = ObservationCovariances(SIGMA)
    covs.add(None, 0)
    assert covs.matrices is None and covs.sigma_floor_m == SIGMA
    covs.add(np.diag([0.01, 0.01, 0.01]), 2)
    assert len(covs.matrices) == 3 and np.allclose(covs.matrices[0], SIGMA ** 2 * np.eye(3))
    with pytest.raises(ValueError, match="finite \\(3, 3\\)"):
        covs.add(np.full((3, 3), np.nan), 3)
    with pytest.raises(ValueError, match="finite \\(3, 3\\)"):
        ModelSelector(paper_settings()).observe([0.0, 0.0, 0.0], cov=np.eye(2))


@pytest.mark.parametrize("track", [static_track, prismatic_track, revolute_track])
def test_fast_update_with_a_covariance_equals_the_full_update(track):
    # fast_update whitens R = L Lᵀ and updates in q's dimension: the same posterior and likelihood.
    rng = np.random.default_rng(4)
    points = track(30, SIGMA, rng)
    A = rng.normal(0.0, 0.03, (30, 3, 3))
    covs = SIGMA ** 2 * np.eye(3) + A @ A.transpose(0, 2, 1)
    full, fast = ModelSelector(paper_settings()), ModelSelector(paper_settings(fast_update=True))
    for z, cov in zip(points, covs):
        mu_full, mu_fast = full.observe(z, cov=cov), fast.observe(z, cov=cov)
        if mu_full is not None:
            np.testing.assert_allclose(mu_fast, mu_full, rtol=1e-7, atol=1e-12)
    for a, b in zip(full.filters, fast.filters):
        np.testing.assert_allclose(b.x, a.x, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(b.P, a.P, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(b.last_update.S, a.last_update.S, rtol=1e-9)


@pytest.mark.parametrize("speed", [0.0, 0.003, 0.03])
def test_running_weighted_motion_test_is_the_array_form(speed):
    # The running sums (O(1) a point) give the array form's p-value at every step, also after the
    # excess variance changes (new sums from the stored covariances), on random covariances and gaps.
    rng = np.random.default_rng(7)
    n = 60
    dts = rng.uniform(0.2, 2.0, n)
    times = np.concatenate([[0.0], np.cumsum(dts[1:])])
    points = np.array([4.0, -3.0, 0.5]) + rng.normal(0.0, SIGMA, (n, 3)) + np.outer(times * speed, [0.6, 0.8, 0.0])
    A = rng.normal(0.0, 0.03, (n, 3, 3))
    covs = SIGMA ** 2 * np.eye(3) + A @ A.transpose(0, 2, 1)
    held = ObservationCovariances(SIGMA)
    for k in range(n):
        held.add(covs[k], k)
        noise_var = SIGMA ** 2 + (0.0 if k < 20 else 0.01 ** 2 if k < 40 else 0.02 ** 2)
        running = held.motion_p_value(None, points[:k + 1], dts[:k + 1], noise_var)
        array = weighted_motion_p_value(points[:k + 1], times[:k + 1], covs[:k + 1], noise_var - SIGMA ** 2)
        assert running == pytest.approx(array, rel=1e-9, abs=1e-300), k


def test_running_weighted_motion_test_fills_points_given_before_the_first_covariance():
    rng = np.random.default_rng(8)
    points = rng.normal(0.0, SIGMA, (12, 3))
    dts = np.ones(12)
    held = ObservationCovariances(SIGMA)
    for k in range(5):
        held.add(None, k)
    for k in range(5, 12):
        held.add(np.diag([0.002, 0.001, 0.003]), k)
    covs = np.array(held.matrices)
    assert held.motion_p_value(None, points, dts, SIGMA ** 2) == pytest.approx(
        weighted_motion_p_value(points, np.arange(12.0), covs, 0.0), rel=1e-9)
