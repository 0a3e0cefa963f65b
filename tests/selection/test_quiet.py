"""quiet_static: the filter bank rests while static holds and the motion test does not reject (docs/selection.md §7)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.selection.selector import ModelSelector

from test_selection import paper_settings, prismatic_track, static_track

SIGMA = 0.04


def _run(points, covs=None, **rest):
    selector = ModelSelector(paper_settings(**rest))
    quiet, p = [], []
    for i, z in enumerate(points):
        selector.observe(z, cov=None if covs is None else covs[i])
        quiet.append(selector.quiet)
        p.append(selector.motion_p_value())
    selector.p_values = np.array(p)
    return selector, quiet


def _covariances(n, rng):
    A = rng.normal(0.0, 0.02, (n, 3, 3))
    return SIGMA ** 2 * np.eye(3) + A @ A.transpose(0, 2, 1)


def test_a_static_point_rests_once_static_is_held_and_mu_stays():
    points = static_track(80, SIGMA, np.random.default_rng(0))
    selector, quiet = _run(points, quiet_static=True)
    awake, _ = _run(points)
    assert selector.held_model == awake.held_model == "static"
    first = quiet.index(True)
    assert all(quiet[first:])
    assert selector.decisions.history[first] == "static"
    rows = selector.mu_history[first:]
    np.testing.assert_array_equal(rows, np.repeat(rows[:1], len(rows), axis=0))  # nothing scored while resting
    # before it rested, the same selector as without the mode
    np.testing.assert_array_equal(selector.mu_history[:first + 1], awake.mu_history[:first + 1])


def test_a_part_first_seen_at_rest_wakes_when_it_moves_as_the_bank_that_never_rested():
    # On waking the bank steps through the observations it rested over, with the refits their
    # schedule made: from then on μ, the filters' states and structures are the awake selector's.
    rng = np.random.default_rng(1)
    points = prismatic_track(90, SIGMA, rng, start=40)
    covs = _covariances(90, rng)
    for given in (None, covs):
        selector, quiet = _run(points, given, quiet_static=True)
        awake, _ = _run(points, given)
        assert any(quiet[:40]) and not quiet[-1]
        woke = max(i for i, q in enumerate(quiet) if q) + 1
        assert woke > 40  # no wake before the part moves
        np.testing.assert_array_equal(selector.mu_history[woke:], awake.mu_history[woke:])
        for f, g in zip(selector.filters, awake.filters):
            np.testing.assert_array_equal(f.x, g.x)
            assert f.structure.residual_m == g.structure.residual_m
        assert selector.held_model == awake.held_model == "prismatic"


@pytest.mark.parametrize("start", [None, 60])
def test_resting_keeps_the_motion_test_of_the_awake_selector(start):
    # The line and circle are refitted on the same schedule while resting, so σ̂², the test and
    # hence the step of waking are those of the selector that never rests.
    rng = np.random.default_rng(3)
    n = 120
    points = (static_track(n, SIGMA, rng) if start is None
              else prismatic_track(n, SIGMA, rng, speed=0.02, start=start))
    covs = _covariances(n, rng)
    selector, quiet = _run(points, covs, quiet_static=True)
    awake, _ = _run(points, covs)
    assert any(quiet)
    np.testing.assert_allclose(selector.p_values, awake.p_values, rtol=1e-9, atol=1e-300)
    if start is not None:
        woke = max(i for i, q in enumerate(quiet) if q) + 1
        assert woke == int(np.argmax(awake.p_values < 1e-3))


@pytest.mark.parametrize("rest", [{"support_alpha": None}, {"refit": False}])
def test_quiet_needs_the_motion_guard_and_refits(rest):
    with pytest.raises(ValueError, match="quiet_static needs"):
        paper_settings(quiet_static=True, **rest)


def test_wake_on_demand_catches_up_to_the_awake_selector():
    # A caller that needs the real μ (A-SLAM, for a landmark not held static) wakes the selector:
    # the bank then is the one that never rested; wake() on an awake selector changes nothing.
    rng = np.random.default_rng(2)
    points = static_track(80, SIGMA, rng)
    covs = _covariances(80, rng)
    selector, awake = ModelSelector(paper_settings(quiet_static=True)), ModelSelector(paper_settings())
    for i, z in enumerate(points):
        if i == 60:
            assert selector.quiet
            selector.wake()
            assert not selector.quiet
            np.testing.assert_array_equal(selector.log_mu, awake.log_mu)
        if i > 60:
            selector.wake()  # each step: it may have gone back to rest
        selector.observe(z, cov=covs[i])
        awake.observe(z, cov=covs[i])
    awake.wake()
    np.testing.assert_array_equal(selector.mu_history[60:], awake.mu_history[60:])


def test_waking_fits_no_window_twice():
    # The refits made while resting fitted the line on their windows: on waking the bank's refits
    # there take those structures, so the line is fitted as often as by the selector that never rests.
    rng = np.random.default_rng(1)
    points = prismatic_track(90, SIGMA, rng, start=40)
    counts = []
    for quiet_static in (True, False):
        selector, count = ModelSelector(paper_settings(quiet_static=quiet_static)), [0]
        line = next(f for f in selector.filters if f.name == "prismatic")
        fit = line.model.fit

        def counted(points_world, fit=fit, count=count):
            count[0] += 1
            return fit(points_world)

        line.model.fit = counted
        rested = False
        for z in points:
            selector.observe(z)
            rested |= selector.quiet
        assert rested == quiet_static and not selector.quiet
        counts.append(count[0])
    assert counts[0] == counts[1] > 3
