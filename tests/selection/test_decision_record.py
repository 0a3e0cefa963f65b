"""Revisable decisions and the decision probabilities (docs/selection.md §1–2)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.selection.decision import DecisionRecord, decision_log_probabilities

NAMES = ("static", "prismatic", "revolute")


def _run(candidates, hold, revise):
    record = DecisionRecord(hold, revise)
    for t, c in enumerate(candidates):
        record.add(t, c)
    return record


def test_first_decision_stays_without_revise():
    record = _run(["prismatic"] * 3 + ["revolute"] * 5, hold=2, revise=False)
    assert (record.first, record.first_step) == ("prismatic", 1)
    assert record.standing == "prismatic" and record.revisions == 0


def test_a_later_held_decision_replaces_the_standing_one():
    record = _run(["prismatic"] * 3 + [None, "revolute", "revolute", "revolute"], hold=2, revise=True)
    assert (record.first, record.first_step) == ("prismatic", 1)
    assert (record.standing, record.standing_step, record.revisions) == ("revolute", 5, 1)


def test_a_candidate_not_held_for_the_hold_time_changes_nothing():
    record = _run(["prismatic"] * 3 + ["revolute", None, "revolute"], hold=2, revise=True)
    assert record.standing == "prismatic" and record.revisions == 0
    assert record.history[-1] == "revolute" and record.held is None


def test_the_run_length_counts_the_latest_candidates_consecutive_steps():
    record = _run(["static"] * 4 + ["revolute", "static", "static"], hold=1, revise=True)
    assert (record.held, record.run_length) == ("static", 2)  # the run before the revolute step does not count
    assert _run([None, None], hold=1, revise=True).run_length == 2 and _run([], 1, True).run_length == 0


def test_decision_probabilities_split_the_moving_mass_by_the_bayes_factor():
    log_mu = np.log([0.1, 0.6, 0.3])
    out = np.exp(decision_log_probabilities(NAMES, log_mu, np.log(4.0)))
    assert out == pytest.approx([0.1, 0.9 / 5, 0.9 * 4 / 5])
    assert np.array_equal(decision_log_probabilities(NAMES, log_mu, None), log_mu)
    dead = np.array([np.log(0.5), -np.inf, np.log(0.5)])  # prismatic not fittable: μ left as it is
    assert np.array_equal(decision_log_probabilities(NAMES, dead, 3.0), dead)
