"""Stamped poses interpolated at any stamp: the MCAP reader's transforms, the bag converter's odometry and truth;
and the checked pose of a message's quaternion and translation, for both readers."""

from __future__ import annotations

import bisect

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

from stslam.errors import InputFileError
from stslam.geometry import pose_matrix


def checked_pose(quaternion, translation, path, what: str) -> np.ndarray:
    """4 × 4 pose (X_parent = R X_child + t) of a message's quaternion (fields x, y, z, w, normalised here) and
    translation (x, y, z); InputFileError naming ``what`` (e.g. "topic /odom: pose") unless both are finite
    and the quaternion is not zero."""
    q = np.array([quaternion.x, quaternion.y, quaternion.z, quaternion.w], dtype=float)
    t = np.array([translation.x, translation.y, translation.z], dtype=float)
    norm = np.linalg.norm(q)
    if not np.isfinite(norm) or norm < 1e-9 or not np.all(np.isfinite(t)):
        raise InputFileError(path, f"{what} has quaternion {q.tolist()} and translation {t.tolist()}; expected "
                                   f"finite values and a non-zero quaternion")
    return pose_matrix(Rotation.from_quat(q / norm).as_matrix(), t)


class PoseTrack:
    """Stamped 4 × 4 poses, interpolated at any stamp (linear in translation, slerp in rotation)."""

    def __init__(self, times=(), poses=()):
        self.times: list[float] = [float(t) for t in times]
        self.poses: list[np.ndarray] = list(poses)

    def at(self, t: float, max_offset: float) -> np.ndarray | None:
        """The pose at ``t``; outside the stamps' span the end pose within ``max_offset`` (s), else None."""
        times = self.times
        if not times:
            return None
        if t <= times[0] or t >= times[-1]:
            k = 0 if t <= times[0] else len(times) - 1
            return self.poses[k] if abs(t - times[k]) <= max_offset else None
        i = bisect.bisect_right(times, t) - 1
        t0, t1 = times[i], times[i + 1]
        f = (t - t0) / (t1 - t0)
        pair = Rotation.from_matrix(np.stack([self.poses[i][:3, :3], self.poses[i + 1][:3, :3]]))
        return pose_matrix(Slerp([0.0, 1.0], pair)([f]).as_matrix()[0],
                           (1 - f) * self.poses[i][:3, 3] + f * self.poses[i + 1][:3, 3])
