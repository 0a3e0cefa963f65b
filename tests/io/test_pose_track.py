"""PoseTrack's interpolation (stslam.io.pose_track): the closed-form slerp against scipy's Slerp."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation, Slerp

from stslam.geometry import pose_matrix
from stslam.io.pose_track import PoseTrack


@settings(max_examples=300, deadline=None)
@given(seed=st.integers(0, 2 ** 32 - 1), f=st.floats(0.0, 1.0), log_angle=st.floats(-9.0, np.log10(np.pi)))
def test_the_interpolated_rotation_is_scipys_slerp(seed, f, log_angle):
    """Between two stamps the rotation is scipy's Slerp to 1e-14 (round-off of a few unit-norm products), for
    arcs from 1e-9 rad (the chord branch) to π, and the translation the linear blend."""
    rng = np.random.default_rng(seed)
    r0 = Rotation.random(random_state=rng)
    axis = rng.normal(size=3)
    r1 = r0 * Rotation.from_rotvec(axis / np.linalg.norm(axis) * 10 ** log_angle)
    t0, t1 = rng.normal(size=3), rng.normal(size=3)
    track = PoseTrack([2.0, 3.0], [pose_matrix(r0.as_matrix(), t0), pose_matrix(r1.as_matrix(), t1)])
    got = track.at(2.0 + f, max_offset=0.0)
    expected = Slerp([0.0, 1.0], Rotation.concatenate([r0, r1]))([f]).as_matrix()[0]
    assert np.allclose(got[:3, :3], expected, rtol=0, atol=1e-14)
    assert np.allclose(got[:3, 3], (1 - f) * t0 + f * t1, rtol=0, atol=1e-14)


def test_stamps_and_ends():
    poses = [pose_matrix(Rotation.from_rotvec([0, 0, a]).as_matrix(), np.array([a, 0, 0])) for a in (0.0, 0.5, 1.0)]
    track = PoseTrack([0.0, 1.0, 2.0], poses)
    assert track.at(1.0, 0.0) is poses[1]  # at a stamp: its pose, not a recomputed one
    assert track.at(2.04, 0.05) is poses[2] and track.at(2.06, 0.05) is None and track.at(-0.01, 0.05) is poses[0]
    half = track.at(1.5, 0.0)
    assert np.allclose(half[:3, :3], Rotation.from_rotvec([0, 0, 0.75]).as_matrix(), atol=1e-15)
    track.poses.append(pose_matrix(np.eye(3), np.zeros(3)))  # appended after a first interpolation: converted too
    track.times.append(3.0)
    assert np.allclose(track.at(2.5, 0.0)[:3, :3], Rotation.from_rotvec([0, 0, 0.5]).as_matrix(), atol=1e-15)


def test_poses_added_as_parts_are_the_checked_poses_to_the_bit():
    """PoseTrack.add keeps a pose's unit quaternion and translation and makes the matrices of those added since
    the last query in one conversion: the same numbers as checked_pose gives each message on its own."""
    from types import SimpleNamespace

    from stslam.io.pose_track import checked_parts, checked_pose

    rng = np.random.default_rng(3)
    messages = [(SimpleNamespace(**dict(zip("xyzw", rng.normal(size=4) * 3))),
                 SimpleNamespace(**dict(zip("xyz", rng.normal(size=3))))) for _ in range(40)]
    track = PoseTrack()
    for k, (q, t) in enumerate(messages[:25]):
        track.add(float(k), *checked_parts(q, t, "f.mcap", "topic /t"))
    assert track.at(3.0, 0.0) is track.poses[3]  # a query makes the matrices
    for k, (q, t) in enumerate(messages[25:], start=25):
        track.add(float(k), *checked_parts(q, t, "f.mcap", "topic /t"))
    track.at(30.5, 0.0)
    assert len(track.poses) == 40
    for pose, (q, t) in zip(track.poses, messages, strict=True):
        np.testing.assert_array_equal(pose, checked_pose(q, t, "f.mcap", "topic /t"))
