"""A-SLAM's revisable decisions (stslam.slam.decisions, SPEC 13, 18)."""

import numpy as np

from stslam.slam.decisions import WindowEvidence, co_moving, preferred_model, revised_model

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
