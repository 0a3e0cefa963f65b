"""Metrics (SPEC 7): ATE and RPE against evo's own API, alignment and structure errors."""

from __future__ import annotations

import copy

import numpy as np
import pytest
from evo.core import metrics as evo_metrics
from evo.core.trajectory import PoseTrajectory3D
from scipy.spatial.transform import Rotation

from stslam.eval.metrics import (AlignmentError, ate_rmse, centre_error, radius_error, relative_translation_errors,
                                 rpe_rmse, umeyama_alignment)
from stslam.io.tum import tum_from_planar

# evo's agreement target (SPEC 7): both implementations do O(n) float64 sums of
# O(1 m) terms, so their difference is round-off, far below 1e-9 m.
EVO_TOL = 1e-9


def _random_tum_3d(rng, n=60):
    t = np.arange(n) * 0.1
    positions = np.cumsum(rng.normal(0.0, 0.3, (n, 3)), axis=0)
    quat_xyzw = Rotation.from_rotvec(np.cumsum(rng.normal(0.0, 0.2, (n, 3)), axis=0)).as_quat()
    return np.column_stack([t, positions, quat_xyzw])


def _random_tum_planar(rng, n=80):
    theta = np.cumsum(rng.normal(0.05, 0.1, n))
    xy = np.cumsum(0.2 * np.column_stack([np.cos(theta), np.sin(theta)]), axis=0)
    return tum_from_planar(np.arange(n, dtype=float), np.column_stack([xy, theta]))


def _noisy(rng, tum, sigma_m=0.05, sigma_rad=0.03):
    out = tum.copy()
    out[:, 1:4] += rng.normal(0.0, sigma_m, (tum.shape[0], 3))
    rot = Rotation.from_quat(tum[:, 4:8]) * Rotation.from_rotvec(rng.normal(0.0, sigma_rad, (tum.shape[0], 3)))
    out[:, 4:8] = rot.as_quat()
    return out


def _rigidly_moved(tum, rotvec, shift):
    """The whole trajectory expressed after a rigid motion of the world: T' = G T."""
    G = Rotation.from_rotvec(rotvec)
    out = tum.copy()
    out[:, 1:4] = G.apply(tum[:, 1:4]) + shift
    out[:, 4:8] = (G * Rotation.from_quat(tum[:, 4:8])).as_quat()
    return out


def _evo_traj(tum):
    quat_wxyz = np.column_stack([tum[:, 7], tum[:, 4:7]])
    return PoseTrajectory3D(positions_xyz=tum[:, 1:4].copy(), orientations_quat_wxyz=quat_wxyz,
                            timestamps=tum[:, 0].copy())


def _evo_ate(gt, est):
    ref, traj = _evo_traj(gt), _evo_traj(est)
    traj = copy.deepcopy(traj)
    traj.align(ref, correct_scale=False)
    ape = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    ape.process_data((ref, traj))
    return ape.get_statistic(evo_metrics.StatisticsType.rmse)


def _evo_rpe(gt, est, delta=1):
    rpe = evo_metrics.RPE(evo_metrics.PoseRelation.translation_part, delta=delta,
                          delta_unit=evo_metrics.Unit.frames, all_pairs=True)
    rpe.process_data((_evo_traj(gt), _evo_traj(est)))
    return rpe.get_statistic(evo_metrics.StatisticsType.rmse)


@pytest.mark.parametrize("make", [_random_tum_3d, _random_tum_planar], ids=["3d", "planar"])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_ate_and_rpe_match_evo_on_noisy_estimates(make, seed):
    rng = np.random.default_rng(seed)
    gt = make(rng)
    est = _noisy(rng, gt)
    ours_ate, evo_ate = ate_rmse(gt, est), _evo_ate(gt, est)
    ours_rpe, evo_rpe = rpe_rmse(gt, est), _evo_rpe(gt, est)
    assert abs(ours_ate - evo_ate) < EVO_TOL
    assert abs(ours_rpe - evo_rpe) < EVO_TOL
    # not a trivial agreement: with σ = 0.05 m per axis the errors are O(0.05–0.1 m)
    assert ours_ate > 0.03 and ours_rpe > 0.03
    for delta in (2, 5):
        assert abs(rpe_rmse(gt, est, delta) - _evo_rpe(gt, est, delta)) < EVO_TOL


@pytest.mark.parametrize("make", [_random_tum_3d, _random_tum_planar], ids=["3d", "planar"])
def test_rigidly_moved_copy_has_zero_ate_and_rpe(make):
    rng = np.random.default_rng(7)
    gt = make(rng)
    rotvec = [0.0, 0.0, 2.1] if make is _random_tum_planar else [0.4, -1.2, 2.1]
    est = _rigidly_moved(gt, rotvec, [3.0, -7.0, 0.5])
    # ATE removes the rigid motion; RPE never sees it (relative motions are frame-free)
    assert ate_rmse(gt, est) < 1e-12
    assert _evo_ate(gt, est) < 1e-12
    assert rpe_rmse(gt, est) < 1e-12
    assert _evo_rpe(gt, est) < 1e-12
    # a deliberately wrong estimate (positions shifted along the path) is far from zero
    wrong = est.copy()
    wrong[:, 1:4] = np.roll(est[:, 1:4], 3, axis=0)
    assert ate_rmse(gt, wrong) > 0.1
    assert abs(ate_rmse(gt, wrong) - _evo_ate(gt, wrong)) < EVO_TOL


def test_rpe_uses_the_relative_rotation_of_the_ground_truth():
    # Ground truth moves 1 m along x per frame without turning. The estimate turns
    # by 90° at frame 1, then moves 1 m along its own (body) x, i.e. world +y: in
    # body frames both relative motions match the truth, so every error is 0. Moving
    # along world +x instead is body −y: error ‖(0,−1,0) − (1,0,0)‖ = √2 for that pair.
    gt = np.zeros((3, 8))
    gt[:, 0] = [0, 1, 2]
    gt[:, 1] = [0.0, 1.0, 2.0]
    gt[:, 7] = 1.0
    est = gt.copy()
    est[1:, 4:8] = Rotation.from_euler("z", np.array([np.pi / 2, np.pi / 2])[:, None]).as_quat()
    est[2, 1:3] = [1.0, 1.0]  # moved 1 m along the rotated body x
    errors = relative_translation_errors(gt, est, delta=1)
    assert errors == pytest.approx([0.0, 0.0], abs=1e-12)  # relative motions agree in body frames
    est_bad = est.copy()
    est_bad[2, 1:3] = [2.0, 0.0]  # moved along world x instead: wrong in the turned body frame
    assert relative_translation_errors(gt, est_bad, 1) == pytest.approx([0.0, np.sqrt(2.0)], abs=1e-12)
    assert rpe_rmse(gt, est_bad) == pytest.approx(1.0, abs=1e-12)  # sqrt((0 + 2) / 2)


def test_umeyama_recovers_a_known_motion():
    rng = np.random.default_rng(4)
    x = rng.normal(size=(30, 3))
    R_true = Rotation.from_rotvec([0.3, 2.0, -1.1]).as_matrix()
    y = x @ R_true.T + [1.0, 2.0, 3.0]
    R, t = umeyama_alignment(x, y)
    assert np.allclose(R, R_true, atol=1e-12) and np.allclose(t, [1.0, 2.0, 3.0], atol=1e-12)
    # a mirrored target must still give a proper rotation
    R_m, _ = umeyama_alignment(x, y * [1.0, 1.0, -1.0])
    assert np.linalg.det(R_m) == pytest.approx(1.0)


@pytest.mark.parametrize("points, match", [
    (np.outer(np.arange(5.0), [1.0, 2.0, 0.0]), "rank ≥ 2, got rank 1"),
    (np.ones((4, 3)), "rank ≥ 2, got rank 0"),
])
def test_degenerate_alignment_raises(points, match):
    with pytest.raises(AlignmentError, match=match):
        umeyama_alignment(points, points + 1.0)


@pytest.mark.parametrize("gt, est, match", [
    (np.zeros((5, 8)), np.zeros((4, 8)), "same shape"),
    (np.zeros((5, 7)), np.zeros((5, 7)), r"tum_gt: expected TUM rows of shape \(n, 8\)"),
    (np.full((5, 8), np.nan), np.zeros((5, 8)), "tum_gt: contains non-finite"),
])
def test_bad_trajectories_raise(gt, est, match):
    with pytest.raises(ValueError, match=match):
        ate_rmse(gt, est)
    with pytest.raises(ValueError, match=match):
        rpe_rmse(gt, est)


def test_rpe_delta_is_checked():
    gt = _random_tum_3d(np.random.default_rng(0), n=4)
    with pytest.raises(ValueError, match="delta: expected an integer ≥ 1, got 0"):
        rpe_rmse(gt, gt, delta=0)
    with pytest.raises(ValueError, match="need more than delta = 4 poses, got 4"):
        rpe_rmse(gt, gt, delta=4)


def test_structure_errors():
    assert centre_error([2.0, 2.0], [2.3, 1.6]) == pytest.approx(0.5)
    assert radius_error(0.9, 1.0) == pytest.approx(0.1)
