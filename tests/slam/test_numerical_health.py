"""Numerical health (issue 12; SPEC 4, 6.3, 6.4): a diverged SLAM filter is flagged in its
metrics, a healthy one is not; long runs keep covariances symmetric positive semi-definite
and model probabilities finite and non-zero.

Already covered elsewhere, not repeated here: 10,000 oracle SLAM steps
(``test_slam_core``), A-SLAM over 1,500 and 10,000 steps (``test_a_slam``), 10,000
threshold-selector steps and the log-probability floor (``test_selection``).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from stslam.selection.selector import ModelSelector
from stslam.config.robot import sensor_from_config
from stslam.config.selection import selection_from_config
from stslam.config.sim import world_from_config
from stslam.config.slam import filter_params_from_config
from stslam.sim.simulate import simulate
from stslam.slam.consistency import NEES_FIRST_FRAME, pose_nees
from stslam.slam.evaluation import (DIVERGENCE_FRACTION, DIVERGENCE_RUN, longest_run, nees_divergence,
                                    run_seed)
from stslam.slam.filters import EkfSlamParams, make_filter, run_filter

from conftest import compose_config

BOUND = chi2.ppf(0.999, 3)  # 16.27
N_FRAMES = 108  # NEES frames of a 110-frame world (from NEES_FIRST_FRAME = 2)


# --- the divergence flag, closed form --------------------------------------------------------

@pytest.mark.parametrize("mask, expected", [
    ([], 0), ([0, 0, 0], 0), ([1], 1), ([1, 1, 0, 1, 1, 1, 0], 3), ([0, 1, 1, 1, 1], 4), ([1] * 7, 7),
])
def test_longest_run_counts_consecutive_true_values(mask, expected):
    assert longest_run(mask) == expected


def test_divergence_needs_both_the_fraction_and_the_run():
    low, high = 1.0, 2.0 * BOUND
    run40 = np.r_[np.full(40, high), np.full(N_FRAMES - 40, low)]  # 37% out, in one run of 40
    assert nees_divergence(run40) == (pytest.approx(40 / N_FRAMES), 1)
    spread = np.where(np.arange(N_FRAMES) % 2 == 0, high, low)  # 50% out, never two in a row
    assert nees_divergence(spread) == (pytest.approx(0.5), 0)
    run30 = np.r_[np.full(30, high), np.full(N_FRAMES - 30, low)]  # a long run, but only 28% out
    assert nees_divergence(run30) == (pytest.approx(30 / N_FRAMES), 0)
    assert nees_divergence(np.full(DIVERGENCE_RUN - 1, high)) == (1.0, 0)  # all out, too short a run
    assert nees_divergence(np.full(DIVERGENCE_RUN, high)) == (1.0, 1)
    with_nan = np.r_[np.full(40, np.nan), np.full(N_FRAMES - 40, low)]  # a singular P counts as out
    assert nees_divergence(with_nan) == (pytest.approx(40 / N_FRAMES), 1)
    frac, flag = nees_divergence([])
    assert np.isnan(frac) and flag == 0
    assert nees_divergence([BOUND * (1 - 1e-12)] * 20) == (0.0, 0)  # the bound itself is in


def test_a_consistent_filter_is_not_flagged_and_a_hundredfold_overconfident_one_is():
    rng = np.random.default_rng(12)
    runs = rng.chisquare(3, size=(5000, N_FRAMES))  # consistent: NEES ~ χ²₃ per frame
    scores = np.array([nees_divergence(r) for r in runs])
    # The fraction out is Binomial(108, 0.001)/108: its mean over 5000 runs is 0.001 with a standard
    # error of √(0.001·0.999/(108·5000)) = 4.3e-5; 4 standard errors allowed. More than a third of
    # 108 frames out has probability < 1e-80: no run may be flagged.
    assert abs(scores[:, 0].mean() - 0.001) < 4 * 4.3e-5
    assert scores[:, 1].sum() == 0
    # Covariance understated c-fold: NEES = c·χ²₃, out with probability p = P(χ²₃ > 16.27/c) per
    # frame. c = 100: p = 0.983, and (independent frames) a run of 10 starts at a given frame with
    # probability p¹⁰ = 0.84, so all 200 runs are flagged (a miss needs ~99 failed starts).
    # c = 2: p = 0.044, none flagged (a third of 108 frames is 8 binomial sd above the mean).
    assert np.all([nees_divergence(100.0 * r)[1] for r in runs[:200]])
    assert not np.any([nees_divergence(2.0 * r)[1] for r in runs[:200]])
    assert DIVERGENCE_FRACTION == pytest.approx(1 / 3)  # the choice documented in stslam.slam.evaluation


# --- the flag on real filters (square_centred, SPEC 8.4) --------------------------------------

@pytest.fixture(scope="module")
def square_centred():
    cfg = compose_config("dynamic_slam")
    return cfg, world_from_config(cfg), sensor_from_config(cfg)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_broken_filter_is_flagged_and_healthy_ones_are_not(square_centred, seed):
    cfg, world, sensor = square_centred
    specs = {
        # EKF SLAM with no random walk on its "static" landmarks: the prismatic and revolute
        # points drag the map and the pose while P shrinks (mean NEES ≈ 250 on seeds 0–9).
        "broken": make_filter("ekf_slam", EkfSlamParams(sigma_walk=0.0), world),
        "oracle": make_filter("oracle", filter_params_from_config(cfg, "oracle"), world),
        "ekf_slam_gated": make_filter("ekf_slam_gated", filter_params_from_config(cfg, "ekf_slam_gated"), world),
    }
    result = run_seed(world, sensor, True, {name: (lambda run, s=s: run_filter(s, run)) for name, s in specs.items()},
                      seed)
    rows = {row["method"]: row for row in result.rows}
    # Measured on seeds 0–9: broken 53–80% of frames out (all flagged); oracle ≤ 17%, gated ≤ 5%.
    # The threshold, 1/3, sits between with a margin of ≥ 0.19 on each side.
    assert rows["broken"]["diverged"] == 1 and rows["broken"]["nees_frac_out"] > 0.5
    for name in ("oracle", "ekf_slam_gated"):
        assert rows[name]["diverged"] == 0 and rows[name]["nees_frac_out"] < 0.2, (name, rows[name])
    # The row's fraction is the one of the per-frame NEES.
    track = result.tracks["broken"]
    nees = pose_nees(world.poses_xytheta, track.poses_xytheta, track.pose_covs)
    assert nees.size == world.n_frames - NEES_FIRST_FRAME
    assert rows["broken"]["nees_frac_out"] == np.mean(nees > BOUND)


# --- long runs: SLAM covariances (SPEC 6.3) -------------------------------------------------

def _slam_long_run(method: str, n_frames: int):
    """Run ``method`` for ``n_frames`` frames of square_centred (16 static landmarks) checking P every frame."""
    cfg = compose_config("dynamic_slam", [f"world.n_frames={n_frames}", "world.static_square.per_side=4"])
    world = world_from_config(cfg)
    run = simulate(world, sensor_from_config(cfg), np.random.default_rng(3))
    worst = []

    def check(k, state):
        P = state.P
        assert np.array_equal(P, P.T), f"P not symmetric at frame {k}"
        assert np.all(np.isfinite(P)) and np.all(np.isfinite(state.x)), f"non-finite state at frame {k}"
        eigenvalues = np.linalg.eigvalsh(P)
        worst.append(eigenvalues[0] / max(eigenvalues[-1], 1e-300))

    track = run_filter(make_filter(method, filter_params_from_config(cfg, method), world), run, observer=check)
    assert len(worst) == n_frames
    # Symmetry is exact (P is symmetrised at every predict and update); the smallest eigenvalue may
    # dip below 0 only by round-off, ~1e-16 × the largest (bound 1e-12).
    assert min(worst) > -1e-12
    assert np.all(np.isfinite(track.poses_xytheta)) and np.all(np.isfinite(track.pose_covs))
    return world, track


@pytest.mark.parametrize("method", ["dyn_slam", "ekf_slam_gated"])
def test_slam_covariance_stays_symmetric_psd_over_1500_frames(method):
    _slam_long_run(method, 1500)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["dyn_slam", "ekf_slam_gated"])
def test_slam_covariance_stays_symmetric_psd_over_10000_frames(method):
    world, track = _slam_long_run(method, 10_000)
    errors = np.linalg.norm(track.poses_xytheta[:, :2] - world.poses_xytheta[:, :2], axis=1)
    _, diverged = nees_divergence(pose_nees(world.poses_xytheta, track.poses_xytheta, track.pose_covs))
    if method == "ekf_slam_gated":
        # Still tracking after 100 loops: median position error below 0.1 m, five times the ~2 cm
        # of a 110-frame run (measured 0.035 m; 0.1% of frames beyond the NEES bound).
        assert np.median(errors) < 0.1 and diverged == 0
    # Dyn. SLAM, with every landmark free to move at a random-walk velocity, has nothing that
    # anchors its map: over 10,000 frames it drifts by metres (measured median 2.8 m) while its
    # covariance claims ~1 m (96% of frames beyond the bound, mean NEES ≈ 3,300). Whatever a
    # filter does, a lost one must say so: metres of error imply the divergence flag.
    if np.median(errors) > 0.5:
        assert diverged == 1


# --- long runs: model selection (SPEC 4) -----------------------------------------------------

def _swinging_door(n: int, rng) -> np.ndarray:
    """A door handle (radius 0.6 m, hinge at the origin, vertical axis) swinging between 0 and 1.6 rad
    with a 300-step period, observed with 2 mm noise per coordinate: (n, 3) m."""
    phi = 0.8 * (1.0 - np.cos(2.0 * np.pi * np.arange(n) / 300.0))
    points = np.column_stack([0.6 * np.cos(phi), 0.6 * np.sin(phi), np.full(n, 1.0)])
    return points + rng.normal(0.0, 0.002, points.shape)


def _selector_long_run(n: int):
    """The IMM of conf/selection/marker_tracks.yaml on a swinging door, μ and every P checked each step."""
    cfg = compose_config("classify_tracks", ["tracks.glob=unused"])
    selector = ModelSelector(selection_from_config(cfg, dt=1.0 / 30.0))
    worst = np.inf
    for t, z in enumerate(_swinging_door(n, np.random.default_rng(8))):
        mu = selector.observe(z)
        if mu is None:
            continue
        assert np.all(np.isfinite(mu)) and np.all(mu > 0.0), f"μ = {mu} at step {t}"
        assert abs(mu.sum() - 1.0) < 1e-12
        for f in selector.filters:
            assert np.array_equal(f.P, f.P.T) and np.all(np.isfinite(f.P)), f"{f.name} P at step {t}"
            eigenvalues = np.linalg.eigvalsh(f.P)
            worst = min(worst, eigenvalues[0] / max(eigenvalues[-1], 1e-300))
    history = selector.mu_history[selector.start_step:]
    assert history.shape == (n - selector.start_step, 3)
    assert np.all(np.isfinite(history)) and np.all(history > 0.0)
    assert worst > -1e-12  # round-off only, as for SLAM
    assert selector.final_model() == "revolute"


def test_imm_selector_keeps_mu_and_covariances_healthy_over_2000_steps():
    _selector_long_run(2000)


@pytest.mark.slow
def test_imm_selector_keeps_mu_and_covariances_healthy_over_10000_steps():
    _selector_long_run(10_000)
