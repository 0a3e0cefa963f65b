"""quiet_static: the filter bank rests while static holds and the motion test does not reject (docs/selection.md §7)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.selection.selector import ModelSelector

from test_selection import paper_settings, prismatic_track, static_track

SIGMA = 0.04


def _run(points, **rest):
    selector = ModelSelector(paper_settings(**rest))
    quiet = []
    for z in points:
        selector.observe(z)
        quiet.append(selector.quiet)
    return selector, quiet


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


def test_a_part_first_seen_at_rest_wakes_when_it_moves_and_is_decided_as_without_resting():
    points = prismatic_track(90, SIGMA, np.random.default_rng(1), start=40)
    selector, quiet = _run(points, quiet_static=True)
    awake, _ = _run(points)
    assert any(quiet[:40]) and not quiet[-1]
    woke = max(i for i, q in enumerate(quiet) if q) + 1
    assert woke > 40  # no wake before the part moves
    assert selector.motion_p_value() < 1e-3
    assert selector.held_model == awake.held_model == "prismatic"


@pytest.mark.parametrize("rest", [{"support_alpha": None}, {"refit": False}])
def test_quiet_needs_the_motion_guard_and_refits(rest):
    with pytest.raises(ValueError, match="quiet_static needs"):
        paper_settings(quiet_static=True, **rest)
