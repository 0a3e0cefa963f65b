"""A-SLAM's onset test (stslam.slam.a_slam._onsets): static points that begin to move are held out."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from stslam.slam.a_slam import _onsets
from stslam.slam.landmark_policy import LandmarkMark
from stslam.slam.loop import Frame

MAX_NIS = 16.27  # χ²₃ at 0.999, the gate


class _State:
    """The two calls _onsets makes of a state, with each landmark's NIS given."""

    def __init__(self, nis):
        self.nis = nis

    def __contains__(self, landmark_id):
        return landmark_id in self.nis

    def observation_nis(self, ids, zs, Rs):
        return np.array([self.nis[i] for i in ids])


def _params():
    return SimpleNamespace(onset_allowance=6.0, onset_threshold=10.0, onset_quiet=5, max_nis=MAX_NIS)


def _frame(k, ids):
    return Frame(k, list(ids), np.zeros((len(ids), 3)), np.repeat(np.eye(3)[None], len(ids), axis=0))


def test_a_point_whose_nis_creeps_up_is_held_out_until_it_rests_again():
    marks = {i: LandmarkMark(None, status="static") for i in range(6)}
    rests = {i: 2.0 for i in range(1, 6)}  # five points at rest: the frame's median NIS stays 2
    held_at = []
    for k, value in enumerate([3.0, 9.0, 10.0, 11.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0]):
        held, nis = _onsets(_State({0: value, **rests}), _frame(k, range(6)), marks, set(), _params())
        assert nis[0] == value and set(held) <= {0}
        if 0 in held:
            held_at.append(k)
            assert held[0] is True  # each of these NIS would pass the gate: held out, not a rejection
    # g: 0, 3, 7, then 12 > 10 at frame 3: suspect; quiet frames 4..8 (five under the allowance) release it
    assert held_at == [3, 4, 5, 6, 7]


def test_a_point_beyond_the_gate_at_once_is_held_and_counts_as_rejected():
    marks = {i: LandmarkMark(None, status="static") for i in range(6)}
    # the frame's median NIS is 1 (allowance 6): 0 + 20 − 6 = 14 > 10 on the first frame
    held, _ = _onsets(_State({0: 20.0, **{i: 1.0 for i in range(1, 6)}}), _frame(0, range(6)), marks, set(), _params())
    assert held == {0: False}
    # a frame whose every NIS is up raises the allowance with its median: the robot is off, no point moved
    marks = {i: LandmarkMark(None, status="static") for i in range(6)}
    held, _ = _onsets(_State({i: 15.0 for i in range(6)}), _frame(0, range(6)), marks, set(), _params())
    assert held == {}
