"""A-SLAM (SPEC 6.3): structure re-expression, invariants of long runs, scores and settings.

Its rows in the `dynamic_slam` experiment are tested in tests/e2e/test_dynamic_slam.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from stslam.articulation.models import PrismaticStructure, RevoluteStructure
from stslam.errors import ConfigError
from stslam.experiments import dynamic_slam
from stslam.config.robot import sensor_from_config
from stslam.config.sim import world_from_config
from stslam.config.slam import a_slam_from_config, filter_params_from_config
from stslam.sim.simulate import simulate
from stslam.slam.a_slam import ASlamTrack, LandmarkReport, run_a_slam
from stslam.slam.decision_scores import SEEN_MOVING_SIGMAS, decision_rows, seen_moving, selection_scores
from stslam.slam.filters import make_filter, run_filter
from stslam.articulation.rebase import inverse_kinematics_derivatives, rebase_motion_state
from stslam.sim.worlds import revolute_structure

from conftest import compose_config

# Central differences with step h on O(1) smooth functions: truncation error ~h²·|f‴| ≈ 1e-12
# and round-off ~ε/h ≈ 1e-10 for h = 1e-6, so 1e-7 is a safe bound for an exact Jacobian
# and far below the O(1) error of a missing term.
FD_STEP, FD_TOL = 1e-6, 1e-7


def _line(p0, direction):
    n = np.asarray(direction, dtype=float)
    return PrismaticStructure(p0=np.asarray(p0, dtype=float), direction=n / np.linalg.norm(n), residual_m=0.0)


def _circle(centre, axis, zero, radius, centre_xy=(0.0, 0.0)):
    base = revolute_structure(centre, axis, zero, radius)
    return RevoluteStructure(p0=base.p0, v1=base.v1, v2=base.v2, centre_xy=np.asarray(centre_xy, dtype=float),
                             radius=radius, residual_m=0.0)


# Lopsided pairs (old, new): a refit moves and tilts the structure a little, or changes its kind.
LINE = _line([1.3, 5.3, 0.1], [1.0, 0.05, -0.02])
LINE_REFIT = _line([1.35, 5.28, 0.12], [0.99, -0.08, 0.03])
CIRCLE = _circle([4.33, 4.33, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], 0.47)
CIRCLE_REFIT = _circle([4.30, 4.37, 0.02], [0.05, -0.03, 1.0], [0.9, 0.3, 0.0], 0.51, centre_xy=(0.01, -0.02))
PAIRS = [(LINE, LINE_REFIT), (CIRCLE, CIRCLE_REFIT), (LINE, _circle([1.8, 7.0, 0.1], [0, 0, 1], [0, -1, 0], 1.7)),
         (CIRCLE, _line([4.0, 4.6, 0.0], [1.0, 0.3, 0.0]))]


def _fd_jacobian(fn, x):
    J = np.empty((fn(x).size, x.size))
    for j in range(x.size):
        e = np.zeros_like(x)
        e[j] = FD_STEP
        J[:, j] = (fn(x + e) - fn(x - e)) / (2 * FD_STEP)
    return J


@pytest.mark.parametrize("old, new", PAIRS, ids=["line-line", "circle-circle", "line-circle", "circle-line"])
@pytest.mark.parametrize("X", [np.array([0.31, 0.043]), np.array([0.8, -0.2, 0.05])], ids=["order1", "order2"])
def test_rebase_jacobian_matches_finite_differences(old, new, X):
    _, J = rebase_motion_state(old, new, X)
    np.testing.assert_allclose(J, _fd_jacobian(lambda v: rebase_motion_state(old, new, v)[0], X), atol=FD_TOL)


@pytest.mark.parametrize("structure", [LINE, CIRCLE], ids=["line", "circle"])
def test_rebase_onto_the_same_structure_is_the_identity(structure):
    X = np.array([0.7, 0.12, -0.01])
    X_new, J = rebase_motion_state(structure, structure, X)
    # IK(f(q)) = q exactly up to round-off on O(1) numbers (and for a circle within (−π, π]).
    np.testing.assert_allclose(X_new, X, atol=1e-12)
    np.testing.assert_allclose(J, np.eye(3), atol=1e-12)


def test_rebase_keeps_the_point_and_its_velocity():
    # The landmark's position and world velocity f′(q)·q̇ are what the filter knows; a refit may
    # only project them onto the new path. For a refitted line through the same point with the
    # same direction, nothing may change; for a tilted one, the speed is the projected one.
    X = np.array([0.5, 0.04])
    X_new, _ = rebase_motion_state(LINE, LINE_REFIT, X)
    point_old = LINE.p0 + X[0] * LINE.direction
    np.testing.assert_allclose(X_new[0], LINE_REFIT.direction @ (point_old - LINE_REFIT.p0), atol=1e-14)
    np.testing.assert_allclose(X_new[1], X[1] * LINE_REFIT.direction @ LINE.direction, atol=1e-14)


def test_revolute_inverse_kinematics_gradient_and_hessian_match_finite_differences():
    m = np.array([4.61, 4.58, 0.07])
    _, grad, hessian = inverse_kinematics_derivatives(CIRCLE_REFIT, m)
    np.testing.assert_allclose(grad, _fd_jacobian(lambda v: np.array([inverse_kinematics_derivatives(
        CIRCLE_REFIT, v)[0]]), m)[0], atol=FD_TOL)
    np.testing.assert_allclose(hessian, _fd_jacobian(lambda v: inverse_kinematics_derivatives(CIRCLE_REFIT, v)[1], m),
                               atol=FD_TOL)
    np.testing.assert_allclose(hessian, hessian.T, atol=1e-15)


def test_inverse_kinematics_on_the_axis_is_rejected():
    with pytest.raises(ValueError, match="undefined on the joint axis"):
        inverse_kinematics_derivatives(CIRCLE, CIRCLE.centre_world)


# --------------------------------------------------------------------------- runs

def _setup(*overrides):
    cfg = compose_config("dynamic_slam", overrides)
    world = world_from_config(cfg)
    return cfg, world, sensor_from_config(cfg)


def test_a_slam_without_decisions_is_the_gated_ekf():
    # SPEC 6.3(a): before any decision every landmark is a gated static point, exactly as in
    # ekf_slam_gated. With selection never fed (no pose is that certain), the two filters run
    # the same arithmetic, so the tracks agree to round-off. (The onset test, which holds out
    # static points that begin to move, is A-SLAM's own: off here.)
    cfg, world, sensor = _setup("filters.a_slam.max_pose_sigma_m=1e-9", "filters.a_slam.onset_allowance=null")
    run = simulate(world, sensor, np.random.default_rng(3))
    a_track = run_filter(make_filter("a_slam", filter_params_from_config(cfg, "a_slam"), world), run)
    gated = run_filter(make_filter("ekf_slam_gated", filter_params_from_config(cfg, "ekf_slam_gated"), world), run)
    np.testing.assert_allclose(a_track.poses_xytheta, gated.poses_xytheta, atol=1e-12)
    np.testing.assert_allclose(a_track.pose_covs, gated.pose_covs, atol=1e-12)
    assert a_track.n_rejected == gated.n_rejected
    assert {report.model for report in a_track.landmarks.values()} == {"undecided"}


def _check_covariance_every_step(n_frames):
    cfg, world, sensor = _setup(f"world.n_frames={n_frames}")
    run = simulate(world, sensor, np.random.default_rng(7))
    worst = {"asym": 0.0, "neg": 0.0}

    def observer(k, state):
        P = state.P
        scale = float(np.max(np.abs(np.diag(P))))
        worst["asym"] = max(worst["asym"], float(np.max(np.abs(P - P.T))) / scale)
        worst["neg"] = max(worst["neg"], -float(np.linalg.eigvalsh(P)[0]) / scale)
        assert np.all(np.isfinite(state.x))

    track = run_a_slam(a_slam_from_config(cfg), run, observer=observer)
    # SPEC 6.3: P stays symmetric PSD. The Joseph-form update and the explicit symmetrisation
    # keep P − Pᵀ at round-off (ε·n ≈ 1e-14 relative); eigenvalues may dip below 0 only by
    # round-off, bounded here by 1e-9 of the largest variance.
    assert worst["asym"] < 1e-12
    assert worst["neg"] < 1e-9
    for report in track.landmarks.values():
        started = report.mu[~np.isnan(report.mu).all(axis=1)]
        assert np.all(np.isfinite(started))
        np.testing.assert_allclose(started.sum(axis=1), 1.0, atol=1e-9)
    return world, track


def test_covariance_stays_symmetric_psd_over_1500_steps():
    world, track = _check_covariance_every_step(1500)
    assert track.poses_xytheta.shape == (1500, 3)
    assert selection_scores(track, world)["correct"] == 1


@pytest.mark.slow
def test_covariance_stays_symmetric_psd_over_10000_steps():
    _check_covariance_every_step(10000)


# ------------------------------------------------------------------------ scores

def _report(model, decisions=(), revisions=0):
    return LandmarkReport(model, tuple(decisions), 0, 0, 0, np.zeros(0, dtype=int), np.zeros((0, 3)),
                          ("static", "prismatic", "revolute"), revisions)


def test_selection_scores_against_the_true_models():
    _, world, _ = _setup()  # 40 static landmarks, then the prismatic (40) and the revolute (41)
    landmarks = {i: _report("static") for i in range(38)}
    landmarks[38] = _report("prismatic")  # a static landmark taken for a drawer
    landmarks[40] = _report("prismatic", [(17, 9, "prismatic")])
    landmarks[41] = _report("revolute", [(95, 8, "prismatic"), (97, 10, "revolute")], revisions=1)
    track = ASlamTrack(np.zeros((1, 3)), np.zeros((1, 3, 3)), 0, landmarks)
    scores = selection_scores(track, world)
    # three articulated decisions; the revolute's first was prismatic, revised once
    assert scores == {"correct": 1, "moving_correct_frac": 1.0, "selection_step": 10.0,
                      "static_correct_frac": 38 / 39, "conversions": 3, "wrong_at_conversion": 1, "revisions": 1}
    rows = {row["landmark"]: row for row in decision_rows(track, world)}
    assert len(rows) == 41 and 39 not in rows  # one row per landmark seen
    assert rows[41] | {} == {"landmark": 41, "true_model": "revolute", "seen_moving": True, "final_model": "revolute",
                            "first_model": "prismatic", "first_frame": 95, "right_frame": 97, "decisions": 2,
                            "revisions": 1, "restarts": 0}
    assert rows[38]["first_model"] == "" and np.isnan(rows[38]["first_frame"])
    landmarks[41] = _report("undecided", [(95, 8, "prismatic")])
    assert selection_scores(track, world)["correct"] == 0
    assert selection_scores(track, world)["moving_correct_frac"] == 0.5
    assert np.isnan(selection_scores(track, world)["selection_step"])


def test_a_mover_never_seen_moving_is_right_when_called_static():
    _, world, _ = _setup()
    landmarks = {i: _report("static") for i in range(40)}
    landmarks[40] = _report("static")  # the drawer, never seen moving
    landmarks[41] = _report("revolute", [(97, 10, "revolute")])
    track = ASlamTrack(np.zeros((1, 3)), np.zeros((1, 3, 3)), 0, landmarks)
    moved = np.zeros(world.n_landmarks, dtype=bool)
    moved[41] = True
    scores = selection_scores(track, world, moved)
    assert scores["correct"] == 1 and scores["moving_correct_frac"] == 1.0
    assert selection_scores(track, world)["correct"] == 0  # without ``moved`` every mover counts as seen moving
    moved[40] = True
    assert selection_scores(track, world, moved)["moving_correct_frac"] == 0.5


def test_seen_moving_from_the_true_positions_at_the_observed_frames():
    _, world, _ = _setup()
    n = world.n_frames
    drawer, door = 40, 41  # the drawer moves 1/30 m per frame, the door π/5 rad per frame
    # Seen only at frames 0 and 3: the drawer moved 0.1 m (< 5σ = 0.2 m), the door ~0.55 m.
    ids = [np.array([drawer, door]) if k in (0, 3) else np.zeros(0, dtype=int) for k in range(n)]
    moved = seen_moving(world, ids, 0.04)
    assert not moved[drawer] and moved[door] and not moved[:40].any()
    ids[10] = np.array([drawer])  # 0.333 m from frame 0
    assert seen_moving(world, ids, 0.04)[drawer]
    assert SEEN_MOVING_SIGMAS * 0.04 == pytest.approx(0.2)


@pytest.mark.parametrize("override, message", [
    ("filters.a_slam.structure_inflation=-1", r"filters.a_slam.structure_inflation: expected a number ≥ 0.0"),
    ("filters.a_slam.restart_after=0", r"filters.a_slam.restart_after: expected an integer ≥ 1"),
    ("filters.a_slam.static_hold=0", r"filters.a_slam.static_hold: expected an integer ≥ 1"),
    ("+filters.a_slam.bodies.evidence_pose=final",
     r"filters.a_slam.bodies.evidence_pose: expected one of static, posterior; got 'final'"),
    ("filters.a_slam.max_pose_sigma_m=0", r"filters.a_slam.max_pose_sigma_m: expected a number > 0.0"),
    ("filters.a_slam.sigma_eta_rad=-0.1", r"filters.a_slam.sigma_eta_rad: expected a number ≥ 0.0"),
    ("selection.models=[static,prismatic]", r"selection.models: A-SLAM needs 'revolute'"),
    ("selection.hold_steps=0", r"selection.hold_steps: expected an integer ≥ 1"),
])
def test_bad_a_slam_settings_fail_before_any_work(compose_exp, override, message):
    cfg = compose_exp("dynamic_slam", "n_seeds=1", "methods=[a_slam]", override)
    with pytest.raises(ConfigError, match=message):
        dynamic_slam.run(cfg)


def test_kept_final_revolute_structure_equals_a_fresh_fit():
    # The common axis reuses each landmark's final revolute fit until its selector has new
    # observations: it must be the fit final_structure makes now, refitted when the selector grows.
    from stslam.slam.landmark_policy import LandmarkPolicy
    policy = LandmarkPolicy(a_slam_from_config(compose_config("dynamic_slam")))
    policy.new_mark(7)
    selector = policy.marks[7].selector
    angles = np.linspace(0.0, 1.5, 40)
    points = np.column_stack([0.6 * np.cos(angles), 0.6 * np.sin(angles), np.full(angles.size, 0.8)])
    for k, point in enumerate(points):
        selector.observe(point + 1e-3 * np.sin(7.0 * k), None)
        if k % 9 == 8:
            kept = policy._final_revolute(7)
            assert policy._final_revolute(7) is kept
            fresh = selector.final_structure("revolute")
            np.testing.assert_array_equal(kept.axis_point, fresh.axis_point)
            np.testing.assert_array_equal(kept.axis_direction, fresh.axis_direction)
            assert kept.radius == fresh.radius


def test_oracle_static_noise_and_a_slam_block_order_follow_the_config():
    # The oracle may give its static points their own σ_η; A-SLAM's articulated blocks take the
    # oracle's temporal order (filters.a_slam.block_order), here 0: q alone, no rates, also at conversion.
    cfg, world, sensor = _setup("filters.oracle.order=0", "filters.oracle.sigma_eta_static_m=0.0",
                                "filters.oracle.sigma_eta_m=0.01", "world.n_frames=60")
    oracle = filter_params_from_config(cfg, "oracle")
    assert (oracle.sigma_eta("static"), oracle.sigma_eta("prismatic"), oracle.sigma_eta("revolute")) == \
        (0.0, 0.01, oracle.sigma_eta_rad)
    params = filter_params_from_config(cfg, "a_slam")
    assert params.block_order == 0 and params.order("revolute") == 0
    run = simulate(world, sensor, np.random.default_rng(0))
    sizes = []
    track = run_filter(make_filter("a_slam", params, world), run,
                       observer=lambda k, state: sizes.extend(state.block(i).size for i in state.landmark_ids
                                                              if hasattr(state.block(i), "model")
                                                              and state.block(i).model.name != "static"))
    assert sizes and set(sizes) == {1}
    assert np.all(np.isfinite(track.poses_xytheta))
    default = filter_params_from_config(_setup()[0], "a_slam")
    assert default.block_order == 1 and default.order("prismatic") == default.selection.filters["prismatic"].order
