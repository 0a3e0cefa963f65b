"""Stamped poses interpolated at any stamp: the MCAP reader's transforms, the bag converter's odometry and truth;
and the checked pose of a message's quaternion and translation, for both readers."""

from __future__ import annotations

import bisect
import math

import numpy as np
from scipy.spatial.transform import Rotation

from stslam.errors import InputFileError
from stslam.geometry import pose_matrix


def checked_pose(quaternion, translation, path, what: str) -> np.ndarray:
    """4 × 4 pose (X_parent = R X_child + t) of a message's quaternion (fields x, y, z, w, normalised here) and
    translation (x, y, z); InputFileError naming ``what`` (e.g. "topic /odom: pose") unless both are finite
    and the quaternion is not zero."""
    q, t = checked_parts(quaternion, translation, path, what)
    return pose_matrix(Rotation.from_quat(q).as_matrix(), t)


def checked_parts(quaternion, translation, path, what: str) -> tuple[np.ndarray, np.ndarray]:
    """The unit quaternion (4,) and translation (3,) of :func:`checked_pose`, checked as it checks them."""
    q = np.array([quaternion.x, quaternion.y, quaternion.z, quaternion.w], dtype=float)
    t = np.array([translation.x, translation.y, translation.z], dtype=float)
    norm = np.linalg.norm(q)
    if not np.isfinite(norm) or norm < 1e-9 or not np.all(np.isfinite(t)):
        raise InputFileError(path, f"{what} has quaternion {q.tolist()} and translation {t.tolist()}; expected "
                                   f"finite values and a non-zero quaternion")
    return q / norm, t


class PoseTrack:
    """Stamped 4 × 4 poses, interpolated at any stamp (linear in translation, slerp in rotation)."""

    def __init__(self, times=(), poses=()):
        self.times: list[float] = [float(t) for t in times]
        self.poses: list[np.ndarray] = list(poses)
        self._quaternions: list[tuple] = []  # (x, y, z, w) of poses[:len], converted on demand, in one batch
        self._parts: list[tuple] = []  # (unit quaternion, translation) of poses still to be made (:meth:`add`)

    def add(self, t: float, quaternion, translation) -> None:
        """Append the pose at stamp ``t`` of a unit quaternion (x, y, z, w) and a translation (:func:`checked_parts`);
        its matrix is made at the next query, together with the others added since (the same numbers)."""
        self.times.append(float(t))
        self._parts.append((quaternion, translation))

    def _made(self) -> list:
        """``poses``, with the matrices of the poses added since made in one conversion."""
        if self._parts:
            rotations = Rotation.from_quat(np.array([q for q, _ in self._parts])).as_matrix()
            self.poses.extend(pose_matrix(R, t) for R, (_, t) in zip(rotations, self._parts))
            self._parts = []
        return self.poses

    def at(self, t: float, max_offset: float) -> np.ndarray | None:
        """The pose at ``t``; outside the stamps' span the end pose within ``max_offset`` (s), else None."""
        times, poses = self.times, self._made()
        if not times:
            return None
        if t <= times[0] or t >= times[-1]:
            k = 0 if t <= times[0] else len(times) - 1
            return poses[k] if abs(t - times[k]) <= max_offset else None
        i = bisect.bisect_right(times, t) - 1
        t0, t1 = times[i], times[i + 1]
        f = (t - t0) / (t1 - t0)
        if f == 0.0:  # at a stamp: its pose itself
            return poses[i]
        if len(self._quaternions) < len(poses):  # poses appended since: convert the new ones together
            new = np.stack(poses[len(self._quaternions):])[:, :3, :3]
            self._quaternions.extend(map(tuple, Rotation.from_matrix(new).as_quat().tolist()))
        return pose_matrix(_slerp_matrix(self._quaternions[i], self._quaternions[i + 1], f),
                           (1 - f) * poses[i][:3, 3] + f * poses[i + 1][:3, 3])


def _slerp_matrix(q0: tuple, q1: tuple, f: float) -> np.ndarray:
    """Rotation matrix a fraction f ∈ [0, 1] along the shorter great arc from unit quaternion q0 to q1 (x, y, z, w):
    q(f) = (sin((1 − f)Ω) q0 + sin(fΩ) q1) / sin Ω, cos Ω = |q0·q1| (Shoemake 1985); on Python floats, as scipy's
    ``Slerp`` would give it (to round-off) at a fiftieth of its cost per call."""
    dot = sum(a * b for a, b in zip(q0, q1))
    if dot < 0.0:  # q and −q are one rotation: take the shorter arc
        q1, dot = tuple(-b for b in q1), -dot
    if dot > 1.0 - 1e-12:  # (nearly) the same rotation: the chord, normalised below
        w0, w1 = 1.0 - f, f
    else:
        omega = math.acos(dot)
        w0, w1 = math.sin((1.0 - f) * omega), math.sin(f * omega)
    x, y, z, w = (w0 * a + w1 * b for a, b in zip(q0, q1))
    norm = math.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
