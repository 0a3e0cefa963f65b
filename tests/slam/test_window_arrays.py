"""WindowEvidence's window arrays and common frames (stslam.slam.bodies.decisions, SPEC 13, 18): the arrays
kept per window and the index intersection give what the sightings give, frame by frame."""

import numpy as np

from stslam.slam.bodies.decisions import WindowEvidence


class _Sighting:
    def __init__(self, p, R, total):
        self.p, self.R, self.total = p, R, total

    def world(self):
        return self.p, self.R, self.total


def _track(rng, frames):
    out = {}
    for f in frames:
        A = rng.normal(size=(3, 3))
        out[int(f)] = _Sighting(rng.normal(size=3), A @ A.T, A @ A.T + np.eye(3))
    return out


def test_common_frames_and_windows_are_the_sightings_at_those_frames():
    rng = np.random.default_rng(7)
    for _ in range(200):
        tracks = {i: _track(rng, np.unique(rng.integers(0, 50, rng.integers(0, 30)))) for i in (1, 2)}
        evidence = WindowEvidence(lambda i: tracks.get(i, {}))
        pa, pb, ca, cb = evidence.common(1, 2)
        frames = sorted(set(tracks[1]) & set(tracks[2]))
        # exact: the same numbers are picked, no arithmetic is done on them
        np.testing.assert_array_equal(pa, np.array([tracks[1][f].p for f in frames]).reshape(-1, 3))
        np.testing.assert_array_equal(pb, np.array([tracks[2][f].p for f in frames]).reshape(-1, 3))
        np.testing.assert_array_equal(ca, np.array([tracks[1][f].R for f in frames]).reshape(-1, 3, 3))
        np.testing.assert_array_equal(cb, np.array([tracks[2][f].R for f in frames]).reshape(-1, 3, 3))
        points, variances = evidence.window(1)
        ordered = sorted(tracks[1])
        np.testing.assert_array_equal(points, np.array([tracks[1][f].p for f in ordered]).reshape(-1, 3))
        np.testing.assert_array_equal(variances, [np.trace(tracks[1][f].total) / 3.0 for f in ordered])


def test_a_window_is_made_again_when_it_changes():
    rng = np.random.default_rng(8)
    track = _track(rng, range(5))
    evidence = WindowEvidence(lambda i: track)
    first, _ = evidence.window(0)
    track[5] = _Sighting(np.full(3, 9.0), np.eye(3), np.eye(3))  # a new sighting: a new latest frame
    del track[0]  # and the oldest dropped
    points, _ = evidence.window(0)
    assert points.shape == (5, 3)
    np.testing.assert_array_equal(points[:-1], first[1:])
    np.testing.assert_array_equal(points[-1], np.full(3, 9.0))
