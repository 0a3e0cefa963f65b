"""The fast routes of online selection against the straightforward ones they replace (to 1e-9)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from stslam.articulation.evidence import MotionStatistics
from stslam.articulation.models import get_model
from stslam.kalman.temporal import MotionModel
from stslam.selection.bank import FilterBank
from stslam.selection.initial_state import evenly_spaced_run, initial_motion_state, step_matrices
from stslam.selection.model_filter import FilterSettings, ModelFilter
from stslam.selection.probabilities import imm_prior, imm_update, markov_matrix, normalise_log, threshold_update
from stslam.selection.selector import ModelSelector
from stslam.selection.settings import make_settings

from joint_paths import joint_path  # tests/selection/joint_paths.py
from stslam.sim.marker_camera import MarkerCamera
from stslam.sim.track_generator import generate_tracks

TOL = dict(rtol=1e-9, atol=1e-12)
NAMES = ("static", "prismatic", "revolute")


def _track(kind: str, n: int = 80, seed: int = 0) -> np.ndarray:
    """A steady motion from the first sample at 30 Hz (revolute 0.8 rad/s)."""
    return joint_path(kind, np.arange(n) / 30.0, 0.8, seed)


def _filters(order: int = 1, fast: bool = True):
    settings = FilterSettings(order=order, sigma_eta=3.0, measurement_sigma_m=0.002, smoothing_sigma=3.0,
                              rerun_steps=10, scale_cap_m=1.0, fast_update=fast)
    return [ModelFilter(get_model(name), settings) for name in NAMES]


@pytest.mark.parametrize("order", [1, 2])
@pytest.mark.parametrize("kind", ["static", "prismatic", "revolute"])
def test_bank_step_equals_the_filters_stepped_one_by_one(kind, order):
    points = _track(kind)
    dts = [1.0 / 30.0] * len(points)
    banked, single = _filters(order), _filters(order)
    for f, g in zip(banked, single):
        f.start(points[:40], dts[:40])
        g.start(points[:40], dts[:40])
    bank = FilterBank(banked)
    assert bank.stacked and bank.scalar == (order == 1)
    for i in range(40, len(points)):
        log_lik, nis, failed = bank.step(range(3), points[i], dts[i])
        assert not failed.any()
        for k, g in enumerate(single):
            update = g.step(points[i], dts[i])
            np.testing.assert_allclose(log_lik[k], update.log_likelihood, **TOL)
            np.testing.assert_allclose(nis[k], update.nis, **TOL)
            np.testing.assert_allclose(banked[k].x, g.x, **TOL)
            np.testing.assert_allclose(banked[k].P, g.P, **TOL)
            np.testing.assert_allclose(banked[k].last_update.S, update.S, **TOL)
            np.testing.assert_allclose(banked[k].last_update.y, update.y, **TOL)


def test_bank_rerun_after_prepare_equals_start():
    points = list(_track("revolute", 120))
    dts = [1.0 / 30.0] * len(points)
    banked, single = _filters(), _filters()
    bank = FilterBank(banked)
    firsts = {f.prepare(points, dts) for f in banked}
    assert len(firsts) == 1 and bank.rerun(range(3), points, dts, firsts.pop()) == []
    for f, g in zip(banked, single):
        g.start(np.array(points), np.array(dts))
        np.testing.assert_allclose(f.x, g.x, **TOL)
        np.testing.assert_allclose(f.P, g.P, **TOL)


@pytest.mark.parametrize("with_cov", [False, True])
def test_bank_rerun_equals_its_steps_one_point_at_a_time(with_cov):
    """The rerun steps all but its last point on Python floats, keeping only the states: the same bits."""
    rng = np.random.default_rng(3)
    points = list(_track("revolute", 120))
    dts = list(1.0 / 30.0 + 0.01 * rng.random(len(points)))
    covs = None
    if with_cov:
        A = rng.normal(size=(len(points), 3, 3)) * 0.002
        covs = A @ A.transpose(0, 2, 1) + 1e-6 * np.eye(3)
    rerun, stepped = FilterBank(_filters()), FilterBank(_filters())
    firsts = {f.prepare(points, dts) for f in rerun.filters} | {f.prepare(points, dts) for f in stepped.filters}
    first = firsts.pop()
    assert not firsts and first < len(points) - 2
    assert rerun.rerun(range(3), points, dts, first, covs) == []
    for i in range(first, len(points)):
        stepped.step(range(3), points[i], dts[i], None if covs is None else covs[i])
    for f, g in zip(rerun.filters, stepped.filters):
        np.testing.assert_array_equal(f.x, g.x)
        np.testing.assert_array_equal(f.P, g.P)
        assert f.last_update.log_likelihood == g.last_update.log_likelihood
        np.testing.assert_array_equal(f.last_update.S, g.last_update.S)


def test_compiled_rerun_stops_before_the_first_failing_step():
    """rerun_rows takes the steps of step_rows one by one (the same bits) and stops before a step where a row
    fails (here P⁻ not finite from the third step's Q on), returning the states before it."""
    from stslam.selection.scalar_rows import rerun_rows, step_rows
    rng = np.random.default_rng(5)
    r, m = 3, 6
    X, P = rng.normal(size=(r, 2)), np.array([[[2e-3, 1e-4], [1e-4, 1e-3]]] * r)
    Qs = np.array([[[[1e-6, 2e-6], [2e-6, 4e-6]]] * r] * m)
    Qs[2:, 1] = np.inf
    hs, Z = 0.03 + 0.01 * rng.random(m), rng.normal(size=(m, 3))
    kinds, packed = np.array([0, 1, 2]), rng.normal(size=(r, 12))
    packed[2, 2] = 0.4  # a radius
    rho = np.full(r, 4e-6)
    args = (kinds, packed, rho, 2.0 * np.log(rho))
    Ls, log_det = np.zeros((m, 3, 3)), np.zeros(m)
    X_rerun, P_rerun, taken = rerun_rows(X, P, Qs, hs, Z, *args, Ls, False, log_det)
    assert taken == 2
    for k in range(3):
        X_new, P_new, *_, failed = step_rows(X, P, Qs[k], hs[k], Z[k], *args, Ls[k], False, 0.0)
        if k == 2:
            assert failed.tolist() == [False, True, False]
            break
        assert not failed.any()
        X, P = X_new, P_new
    np.testing.assert_array_equal(X_rerun, X)
    np.testing.assert_array_equal(P_rerun, P)


def test_bank_without_the_fast_update_steps_each_filter():
    bank = FilterBank(_filters(fast=False))
    assert not bank.stacked and not bank.scalar


def _settings(**rest):
    return make_settings({"static": 0.01, "prismatic": 3.0, "revolute": 3.0}, measurement_sigma_m=0.002,
                         smoothing_sigma=3.0, rerun_steps=10, scale_cap_m=1.0, fast_update=True, dt=1.0 / 30.0,
                         selector="imm", tau=0.9, hold_steps=15, min_motion_m=0.1, fit_spacing_m=0.005,
                         refit_extent_floor_m=0.02, **rest)


def test_selector_with_the_bank_equals_the_selector_stepping_each_filter():
    settings = _settings()
    for track in generate_tracks(6, 3, camera=MarkerCamera()):
        fast, plain = ModelSelector(settings), ModelSelector(settings)
        plain._bank.stacked = plain._bank.scalar = False  # the straightforward loop over ModelFilter.step
        for z in track.points_world:
            fast.observe(z)
            plain.observe(z)
        np.testing.assert_allclose(fast.mu_history, plain.mu_history, **TOL)
        assert fast.final_decision() == plain.final_decision()


def test_step_matrices_equal_the_motion_model():
    for order in (0, 1, 2):
        for dt in (1.0, 1.0 / 30.0, 0.0371):
            F, Q = step_matrices(order, 1, dt, 0.37)
            F0, Q0 = MotionModel(order, 1, 0.37).matrices(dt)
            np.testing.assert_array_equal(F, F0)
            np.testing.assert_array_equal(Q, Q0)


def test_initial_state_of_one_axis_equals_the_kronecker_form():
    q = np.cumsum(np.random.default_rng(1).normal(size=(7, 1)), axis=0)
    x, P = initial_motion_state(q, 1, 0.1, 3.0, [0.02])
    from stslam.selection.initial_state import derivative_gains
    G = derivative_gains(7, 1, 0.1, 3.0)
    np.testing.assert_allclose(P, np.kron(G @ G.T, np.diag([0.02 ** 2])), **TOL)
    np.testing.assert_allclose(x, (G @ q).reshape(-1), **TOL)


def _evenly_spaced_run_numpy(dts, first, m, gap_factor=1.5):
    dts = np.asarray(dts, dtype=float)
    if m <= 1:
        return first, m
    gaps = dts[first + 1:first + m]
    breaks = np.flatnonzero(gaps > gap_factor * np.min(gaps)) + first + 1
    starts, ends = np.concatenate([[first], breaks]), np.concatenate([breaks, [first + m]])
    for start, end in zip(starts[::-1], ends[::-1]):
        if end - start >= 2:
            return int(start), int(end - start)
    return first + m - 1, 1


def test_evenly_spaced_run_equals_the_array_form():
    rng = np.random.default_rng(2)
    for _ in range(200):
        dts = rng.choice([0.033, 0.034, 0.1, 0.5], size=20)
        first, m = int(rng.integers(0, 10)), int(rng.integers(1, 10))
        assert evenly_spaced_run(list(dts), first, m) == _evenly_spaced_run_numpy(dts, first, m)


def test_fast_probability_updates_equal_the_masked_ones():
    rng = np.random.default_rng(3)
    Pi = markov_matrix(3, 0.98)
    for _ in range(100):
        log_mu = normalise_log(rng.normal(size=3) * 5)
        log_lik = rng.normal(size=3) * 20
        reference = normalise_log(imm_prior(log_mu, Pi) + log_lik)
        np.testing.assert_allclose(imm_update(log_mu, log_lik, Pi, np.log(Pi)), reference, **TOL)
        np.testing.assert_allclose(threshold_update(log_mu, log_lik), normalise_log(log_mu + log_lik), **TOL)


def test_motion_statistics_equal_the_direct_sums():
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.02, 0.05, 50))
    z = rng.normal(size=(50, 3)) + [100.0, -50.0, 3.0]
    stats_ = MotionStatistics()
    for ti, zi in zip(t, z):
        stats_.add(ti, zi)
    dz, dt = z - z.mean(axis=0), t - t.mean()
    np.testing.assert_allclose(stats_.szz, np.sum(dz ** 2), **TOL)
    np.testing.assert_allclose(stats_.stz, dt @ dz, **TOL)
    np.testing.assert_allclose(stats_.mean_z, z.mean(axis=0), **TOL)
    b = (dt @ dz) / (dt @ dt)
    p_trend = stats.chi2.sf(b @ b * (dt @ dt) / 1e-2, 3)
    p_spread = stats.chi2.sf(np.sum(dz ** 2) / 1e-2, 3 * 49)
    np.testing.assert_allclose(stats_.p_value(1e-2), min(1.0, 2 * min(p_trend, p_spread)), rtol=1e-9, atol=1e-300)


def test_batch_ranks_of_stacked_hypotheses_equal_one_by_one():
    from stslam.selection.batch import _cross, _hypothesis, _stacked_distances, distances
    rng = np.random.default_rng(5)
    points = _track("revolute", 60)
    for name, size in (("static", 1), ("prismatic", 2), ("revolute", 3)):
        hypotheses = [h for h in (_hypothesis(name, points[rng.choice(60, size, replace=False)]) for _ in range(20))
                      if h is not None]
        stacked = _stacked_distances(name, points, hypotheses)
        for row, h in zip(stacked, hypotheses):
            np.testing.assert_allclose(row, distances(name, points, h), **TOL)
    for _ in range(50):
        a, b = rng.normal(size=3), rng.normal(size=3)
        np.testing.assert_allclose(_cross(a, b), np.cross(a, b), **TOL)


def test_whitening_on_floats_equals_numpy_cholesky():
    from stslam.selection.bank import _whitening
    rng = np.random.default_rng(5)
    for _ in range(200):
        A = rng.normal(0.0, 0.03, (3, 3))
        C = 0.04 ** 2 * np.eye(3) + A @ A.T
        inverse, log_det, _ = _whitening(C)
        L = np.linalg.cholesky(C)
        np.testing.assert_allclose(np.array(inverse), np.linalg.inv(L), rtol=1e-9, atol=1e-12)
        assert log_det == pytest.approx(float(np.log(np.diag(L)).sum()), rel=1e-12)
    assert _whitening(np.diag([1.0, -1.0, 1.0])) is None and _whitening(np.ones((3, 3))) is None


def test_small_mean_equals_numpy_mean():
    """prepare's δt₀: the mean of a few gaps on Python floats, the same bits as np.mean (and np.mean from 8 on)."""
    from stslam.selection.model_filter import small_mean
    rng = np.random.default_rng(11)
    for n in range(1, 12):
        for _ in range(300):
            values = rng.random(n) * 10.0 ** rng.integers(-3, 3)
            if rng.random() < 0.5:
                values = np.round(values, 3) / 30.0
            assert small_mean(values) == float(np.mean(values))
