"""A-SLAM's revisable decisions (stslam.slam.bodies.decisions, SPEC 13, 18)."""

import numpy as np

from stslam.slam.a_slam_settings import BodySettings
from stslam.slam.bodies.decisions import (WindowEvidence, body_revisions, co_moving, conversion_model, preferred_model,
                                          revised_model, selector_action)

SIGMA = 0.04


def test_revision_needs_the_margin():
    assert revised_model("prismatic", 3.5, 3.0) == "revolute"
    assert revised_model("prismatic", 2.5, 3.0) is None  # hysteresis: near even, nothing flaps
    assert revised_model("revolute", -3.5, 3.0) == "prismatic"
    assert revised_model("revolute", 10.0, 3.0) is None
    assert preferred_model(0.1) == "revolute" and preferred_model(0.0) == "prismatic"


class _Sighting:
    def __init__(self, p):
        self.p = p

    def world(self):
        R = SIGMA ** 2 * np.eye(3)
        return self.p, R, R


def _drawer(start, rng, travel=0.4):
    """Positions over 60 frames: at rest, sliding along y from frame ``start`` for 10 frames, at rest."""
    s = np.clip((np.arange(60) - start) / 10.0, 0.0, 1.0) * travel
    return np.column_stack([np.full(60, 4.0), s, np.full(60, 0.8)]) + rng.normal(0.0, SIGMA, (60, 3))


def test_points_of_one_part_co_move_and_two_drawers_in_turn_do_not():
    rng = np.random.default_rng(0)
    a, b = _drawer(20, rng), _drawer(20, rng) + np.array([0.0, 0.0, 0.2])
    c = _drawer(40, rng) + np.array([0.6, 0.0, 0.4])
    assert co_moving(a, b)
    assert not co_moving(a, c)
    tracks = {1: a, 2: b, 3: c}
    evidence = WindowEvidence(lambda i: {k: _Sighting(p) for k, p in enumerate(tracks[i])})
    links = evidence.links([1, 2, 3], significance=0.01, min_motion_m=0.1, min_common=10)
    assert links == {1: {2}, 2: {1}, 3: set()}
    # the linked pair of one drawer votes for a slide; its points' windows lean the same way
    assert evidence.group_log_odds([1, 2], {frozenset((1, 2))}) < 0


def test_window_evidence_is_recomputed_only_when_the_window_changes():
    rng = np.random.default_rng(1)
    track = {k: _Sighting(p) for k, p in enumerate(_drawer(20, rng))}
    evidence = WindowEvidence(lambda i: track)
    first = evidence.log_odds(7)
    track[60] = _Sighting(np.array([4.0, 0.4, 0.8]))
    assert evidence.log_odds(7) != first or len(evidence.window(7)[0]) == 61
    assert len(evidence.window(7)[0]) == 61
    assert evidence.structure(7, "prismatic") is not None


CONVERT = ("prismatic", "revolute")


def test_the_selectors_verdict_and_what_it_does():
    # (model, block status, verdict, seen moving, convert, revises) -> action
    assert selector_action("undecided", "undecided", None, False, CONVERT, True) is None
    assert selector_action("static", "static", "static", False, CONVERT, True) is None  # nothing new
    assert selector_action("undecided", "undecided", "prismatic", False, CONVERT, True) == "convert"
    assert selector_action("undecided", "undecided", "revolute", False, ("prismatic",), True) == "hold"
    assert selector_action("revolute", "revolute", "static", False, CONVERT, True) == "static"
    assert selector_action("revolute", "revolute", "static", True, CONVERT, True) is None  # SPEC 16: seen moving
    # undoing a conversion waits until the static verdict has stood static_hold observations; a static
    # verdict for a point that was never articulated needs no such wait
    assert selector_action("revolute", "revolute", "static", False, CONVERT, True, 4, 5) is None
    assert selector_action("revolute", "revolute", "static", False, CONVERT, True, 5, 5) == "static"
    assert selector_action("undecided", "undecided", "static", False, CONVERT, True, 1, 5) == "static"
    # between the moving models the selector decides only when the window does not (revises off)
    assert selector_action("revolute", "revolute", "prismatic", False, CONVERT, False) == "rebase"
    assert selector_action("revolute", "revolute", "prismatic", False, CONVERT, True) is None
    assert selector_action("revolute", "revolute", "prismatic", False, ("revolute",), False) is None
    # a pending conversion to a model the selector no longer holds is replaced
    assert selector_action("prismatic", "static", "revolute", False, CONVERT, True) == "convert"


class _Evidence:
    """A window of ``n`` sightings whose revolute : prismatic log-odds is ``log_odds``."""

    def __init__(self, n, log_odds):
        self.n, self.value = n, log_odds

    def size(self, landmark_id):
        return self.n

    def log_odds(self, landmark_id):
        return self.value


def test_a_conversion_takes_the_windows_model_only_when_it_is_clear():
    assert conversion_model(_Evidence(60, -5.0), 1, "revolute", 3.0, CONVERT) == "prismatic"
    assert conversion_model(_Evidence(60, 5.0), 1, "prismatic", 3.0, CONVERT) == "revolute"
    assert conversion_model(_Evidence(60, -2.0), 1, "revolute", 3.0, CONVERT) == "revolute"  # not clear
    assert conversion_model(_Evidence(60, -5.0), 1, "revolute", 3.0, ("revolute",)) == "revolute"  # not allowed
    assert conversion_model(_Evidence(2, -5.0), 1, "revolute", 3.0, CONVERT) == "revolute"  # too few sightings


def test_a_body_called_a_hinge_whose_points_slide_is_revised():
    # three corners of one drawer front (an L: pairs along x and along z) sliding 0.8 m: on this seed the
    # group's log-odds are -5.5 (windows -2.5, quiet pairs -3), past the margin 3
    rng = np.random.default_rng(0)
    corners = {1: [0.0, 0.0, 0.0], 2: [0.3, 0.0, 0.0], 3: [0.0, 0.0, 0.3]}
    tracks = {i: _drawer(20, rng, travel=0.8) + np.array(corners[i]) for i in (1, 2, 3)}
    evidence = WindowEvidence(lambda i: {k: _Sighting(p) for k, p in enumerate(tracks[i])})
    settings = BodySettings()
    out = body_revisions(evidence, {1: ("revolute", [2, 3], False)}, [1, 2, 3], settings, CONVERT)
    assert [(f, m) for f, m, _ in out] == [(1, "prismatic")]
    assert out[0][2] is not None  # its structure, fitted to the founder's window
    assert body_revisions(evidence, {1: ("prismatic", [2, 3], False)}, [1, 2, 3], settings, CONVERT) == []
    assert body_revisions(evidence, {1: ("revolute", [2, 3], True)}, [1, 2, 3], settings, CONVERT) == []  # pending
    assert body_revisions(evidence, {1: ("revolute", [2, 3], False)}, [1, 2, 3], settings, ("revolute",)) == []
    # a lone point (a body of one) on the same evidence does not clear the margin: one window is weak
    assert body_revisions(evidence, {3: ("revolute", [], False)}, [3], settings, CONVERT) == []


def test_quiet_pairs_along_one_line_do_not_call_a_body_a_slider():
    # the same slide seen by three points up one vertical line: a door turning about a vertical hinge
    # through them would leave every pair's difference unchanged too, so the pairs say nothing and
    # the windows' -2.5 alone stays inside the margin
    rng = np.random.default_rng(0)
    tracks = {i: _drawer(20, rng, travel=0.8) + np.array([0.0, 0.0, 0.3 * (i - 1)]) for i in (1, 2, 3)}
    evidence = WindowEvidence(lambda i: {k: _Sighting(p) for k, p in enumerate(tracks[i])})
    linked = {frozenset(p) for p in ((1, 2), (1, 3), (2, 3))}
    assert evidence.group_log_odds([1, 2, 3], linked) == 0.5 * evidence.pooled([1, 2, 3])  # POINT_WEIGHT
    assert body_revisions(evidence, {1: ("revolute", [2, 3], False)}, [1, 2, 3], BodySettings(), CONVERT) == []


def test_a_member_of_another_part_does_not_vote_for_a_turn():
    # A drawer body (two corners) with a point of a door that opens while the drawer rests grouped into
    # it by mistake (kitchen seed 1014: a dishwasher point in the low drawer's body turned it revolute).
    # Their difference changes (a turn's mark), but they do not move at the same times: no pair of one
    # body, no vote.
    rng = np.random.default_rng(3)
    phi = np.clip((np.arange(60) - 35) / 10.0, 0.0, 1.0) * 1.2
    door = np.column_stack([2.0 + 0.4 * np.cos(phi), 0.4 * np.sin(phi), np.full(60, 0.5)])
    door = door + rng.normal(0, SIGMA, (60, 3))
    tracks = {1: _drawer(10, rng), 2: _drawer(10, rng) + np.array([0.3, 0.0, 0.0]), 3: door}
    evidence = WindowEvidence(lambda i: {k: _Sighting(p) for k, p in enumerate(tracks[i])})
    linked = {frozenset(p) for p in ((1, 2), (1, 3), (2, 3))}
    keys = {i: evidence._key(i) for i in (1, 2, 3)}
    assert evidence._turn(1, 3, keys).log_odds > 0  # without the guard: a turn
    fresh = WindowEvidence(lambda i: {k: _Sighting(p) for k, p in enumerate(tracks[i])})
    settings = BodySettings()
    assert fresh._turn(1, 3, keys, settings).log_odds == 0.0
    assert fresh.group_log_odds([1, 2, 3], linked, settings) < fresh.group_log_odds([1, 2, 3], linked) - 10
