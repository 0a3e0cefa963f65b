"""The refit schedule (stslam.selection.schedule) and its use by the selector."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stslam.articulation.models import get_model
from stslam.selection.nested_price import NestedPrice
from stslam.selection.schedule import MAX_GROWTH, RefitSchedule, judged_models, structure_shift
from stslam.selection.selector import select_track
from stslam.selection.settings import make_settings

from joint_paths import joint_path  # tests/selection/joint_paths.py

GROWTH = 1.2


def _refits(schedule: RefitSchedule, n_total: int, extent_at, quiet: bool) -> list[int]:
    """Run a schedule over a track of n_total observations; the counts at which it refits."""
    schedule.start(7, extent_at(7))
    refits = []
    for n in range(8, n_total + 1):
        if schedule.due(n, extent_at(n)):
            schedule.done(n, extent_at(n), quiet)
            refits.append(n)
    return refits


@pytest.mark.parametrize("quiet", [False, True])
def test_refits_on_a_long_moving_track_are_logarithmic(quiet):
    n_total = 100_000
    schedule = RefitSchedule(GROWTH, 0, 0.02, 0.002, converged=True)
    refits = _refits(schedule, n_total, lambda n: 0.001 * n, quiet)
    # count trigger and extent trigger each at most log_g(n_total / 7) + 1 times
    bound = 2 * (math.log(n_total / 7) / math.log(GROWTH) + 1)
    assert len(refits) <= bound
    assert len(refits) == schedule.count


def test_quiet_refits_double_the_interval_in_the_count_and_a_moving_one_resets_it():
    schedule = RefitSchedule(GROWTH, 0, 0.02, 0.002, converged=True)
    schedule.start(100, 0.5)
    factors = []
    for quiet in (True, True, True, True, False):
        schedule.done(schedule.n_last + 10, 0.5, quiet)
        factors.append(schedule.factor)
    assert factors[:4] == pytest.approx([1.4, 1.8, MAX_GROWTH, MAX_GROWTH])
    assert factors[4] == GROWTH
    # a resting track (extent fixed): quiet refits thin the count trigger geometrically
    resting = _refits(RefitSchedule(GROWTH, 0, 0.02, 0.002, converged=True), 20_000, lambda n: 0.5, True)
    plain = _refits(RefitSchedule(GROWTH, 0, 0.02, 0.002, converged=False), 20_000, lambda n: 0.5, True)
    assert len(resting) < 0.45 * len(plain)
    assert all(b >= 1.99 * a for a, b in zip(resting[3:], resting[4:]))


def test_the_extent_trigger_is_not_thinned():
    schedule = RefitSchedule(GROWTH, 0, 0.02, 0.002, converged=True)
    schedule.start(100, 0.1)
    for _ in range(5):
        schedule.done(schedule.n_last, 0.1, True)
    assert schedule.factor == MAX_GROWTH
    assert not schedule.due(101, 0.1 * GROWTH * 0.999)
    assert schedule.due(101, 0.1 * GROWTH)


def test_no_structure_refitted_keeps_the_quiet_run():
    schedule = RefitSchedule(GROWTH, 0, 0.0, 0.002, converged=True)
    schedule.start(10, 0.1)
    schedule.done(12, 0.1, True)
    schedule.done(15, 0.1, None)
    assert schedule.quiet_run == 1 and schedule.count == 2


def test_without_thinning_the_factor_is_the_growth():
    schedule = RefitSchedule(GROWTH, 0, 0.0, 0.002, converged=False)
    schedule.start(10, 0.1)
    for _ in range(4):
        schedule.done(schedule.n_last + 2, 0.1, True)
    assert schedule.factor == GROWTH


def test_structure_shift_is_in_standard_errors():
    rng = np.random.default_rng(0)
    model = get_model("prismatic")
    window = np.outer(np.linspace(0.0, 0.5, 50), [1.0, 0.0, 0.0]) + rng.normal(0.0, 0.002, (50, 3))
    line = model.fit(window)
    assert structure_shift(model, line, line, window, 0.002, 4) == 0.0
    sigma, p, n = 0.002, 4, window.shape[0]
    offset = 3.0 * sigma * math.sqrt(p / n)  # move the line sideways by three standard errors
    moved = type(line)(p0=line.p0 + offset * np.array([0.0, 0.0, 1.0]), direction=line.direction,
                       residual_m=line.residual_m)
    assert structure_shift(model, line, moved, window, sigma, p) == pytest.approx(3.0, rel=0.05)


def test_judged_models_leave_out_what_the_guards_rule_out_and_the_less_likely_nested_model():
    names = ("static", "prismatic", "revolute")
    log_mu = np.log([0.01, 0.2, 0.79])
    assert judged_models(names, log_mu, lambda name: name != "static", None) == {1, 2}
    assert judged_models(names, log_mu, lambda name: name != "static", NestedPrice()) == {2}
    assert judged_models(names, log_mu, lambda name: True, NestedPrice()) == {0, 2}


def _settings(converged: bool):
    return make_settings({"static": 0.01, "prismatic": 3.0, "revolute": 3.0}, measurement_sigma_m=0.002,
                         smoothing_sigma=3.0, rerun_steps=5, scale_cap_m=1.0, fast_update=True, dt=1.0 / 30.0,
                         selector="imm", tau=0.9, hold_steps=15, min_motion_m=0.1, fit_spacing_m=0.005,
                         refit_extent_floor_m=0.02, revise=True, nested_price=NestedPrice(), settle_steps=10,
                         outlier_nis=30.0, refit_converged=converged)


def _clean_track(kind: str, n: int, seed: int = 0) -> np.ndarray:
    """A rest of 1 s, then a steady opening at 30 Hz, then a long rest; 2 mm noise."""
    return joint_path(kind, np.clip((np.arange(n) - 30) / 60.0, 0.0, 1.0), 1.2, seed)  # 0 → 1 over 2 s


@pytest.mark.parametrize("kind", ["prismatic", "revolute"])
def test_convergence_thinning_keeps_the_decision_on_a_clean_track(kind):
    track = _clean_track(kind, 400)
    thinned, plain = select_track(track, _settings(True)), select_track(track, _settings(False))
    assert thinned.final_decision() == plain.final_decision()  # model, step and how
    assert thinned.final_decision()[0] == kind
    assert thinned.schedule.count <= plain.schedule.count


def test_refits_on_a_long_track_are_bounded_by_its_log_and_thinned_once_settled():
    n = 3000  # the opening, then 90 s of rest
    track = _clean_track("revolute", n)
    selector, plain = select_track(track, _settings(True)), select_track(track, _settings(False))
    assert selector.final_decision()[0] == plain.final_decision()[0] == "revolute"
    bound = 2 * (math.log(n / 7) / math.log(GROWTH) + 1)
    assert selector.schedule.count <= bound and selector.price_schedule.count <= bound
    # settled, the price's refits stop moving its curvature: its schedule thins
    assert selector.price_schedule.count < 0.8 * plain.price_schedule.count


def test_a_moving_track_settles_and_its_bank_stops_a_resting_one_never_settles():
    moving = select_track(_clean_track("prismatic", 400), _settings(True))
    mu = moving.mu_history
    assert moving.settled and np.array_equal(mu[-200:], np.repeat(mu[-1:], 200, axis=0))
    rng = np.random.default_rng(1)
    resting = select_track([0.3, -0.2, 1.1] + rng.normal(0.0, 0.002, (400, 3)), _settings(True))
    assert not resting.settled and resting.final_decision()[0] in ("static", None)  # it never moved 0.1 m
