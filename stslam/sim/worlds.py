"""Simulated worlds: landmarks with their true articulation and a robot path (SPEC 8.4).

Every landmark carries its *true* model, structure and motion variable q per
frame; its position is f(C, q) from :mod:`stslam.articulation.models`, so an
oracle that is handed (model, structure) explains the landmark exactly. Worlds
are described in ``conf/world/<name>.yaml`` (keys: :mod:`stslam.config.sim`).

Units: metres, radians; times in frames (frame k is at time k·δt seconds).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stslam.articulation.models import RevoluteStructure, get_model
from stslam.robot.motion import move


@dataclass(frozen=True, eq=False)
class LandmarkTruth:
    """One landmark's ground truth.

    Attributes
    ----------
    name : str
    model_name : {"static", "prismatic", "revolute"}
    structure : StaticStructure | PrismaticStructure | RevoluteStructure
        The exact structure C (SPEC 2).
    q : numpy.ndarray, shape (n_frames, 1)
        Motion variable per frame (m or rad).
    body : str or None
        Name of the rigid part the point belongs to (SPEC 13; its points share q),
        None for a landmark of its own.
    """

    name: str
    model_name: str
    structure: object
    q: np.ndarray
    body: str | None = None

    @property
    def model(self):
        return get_model(self.model_name)

    def positions(self) -> np.ndarray:
        """World positions f(C, q(k)) per frame, shape (n_frames, 3), m."""
        return self.model.position(self.structure, self.q)


@dataclass(frozen=True, eq=False)
class World:
    """Ground truth of a simulated run.

    Attributes
    ----------
    name : str
    dt : float
        Seconds per frame.
    alpha : numpy.ndarray, shape (4,)
        Control-noise coefficients (SPEC 5.1).
    poses_xytheta : numpy.ndarray, shape (n_frames, 3)
        True robot poses (x m, y m, θ rad), world frame.
    landmarks : tuple[LandmarkTruth, ...]
    positions : numpy.ndarray, shape (n_frames, n_landmarks, 3)
        True landmark positions per frame (m, world frame).
    """

    name: str
    dt: float
    alpha: np.ndarray
    poses_xytheta: np.ndarray
    landmarks: tuple
    positions: np.ndarray

    @property
    def n_frames(self) -> int:
        return self.poses_xytheta.shape[0]

    @property
    def n_landmarks(self) -> int:
        return len(self.landmarks)


# ------------------------------------------------------------------ pure builders

def circle_path(centre_xy, radius_m: float, start_angle_rad: float, angle_step_rad: float,
                n_frames: int) -> np.ndarray:
    """Poses on a circle: position c + r(cos a_k, sin a_k), a_k = a_0 + k·Δa, heading a_k ± π/2.

    The heading is tangent in the direction of travel (+π/2 for Δa > 0,
    counter-clockwise). Consecutive poses lie on one arc of the SPEC 5.1 model
    with v = rΔa/δt, ω = Δa/δt. Returns shape (n_frames, 3).
    """
    k = np.arange(n_frames, dtype=float)
    angle = start_angle_rad + k * angle_step_rad
    turn = np.pi / 2 if angle_step_rad >= 0 else -np.pi / 2
    return np.column_stack([centre_xy[0] + radius_m * np.cos(angle),
                            centre_xy[1] + radius_m * np.sin(angle), angle + turn])


def segments_path(start_pose, segments, dt: float) -> np.ndarray:
    """Poses by driving the SPEC 5.1 model from ``start_pose`` with piecewise-constant (v, ω).

    ``segments`` is a list of (v m/s, ω rad/s, frames); returns shape (1 + Σ frames, 3).
    """
    poses = [np.asarray(start_pose, dtype=float)]
    for v, w, frames in segments:
        for _ in range(int(frames)):
            poses.append(move(poses[-1], (v, w), dt))
    return np.array(poses)


def square_perimeter_points(low: float, high: float, per_side: int, z_low: float,
                            z_high: float) -> np.ndarray:
    """Points on the perimeter of the square [low, high]², ``per_side`` on each side.

    Sides run counter-clockwise (bottom: x up; right: y up; top: x down; left: y
    down), each from one corner to the next with spacing (high − low)/(per_side − 1),
    so each corner appears twice (as the last point of one side and the first of
    the next). Heights follow the same deterministic ramp on every side:
    z_i = z_low + i·(z_high − z_low)/(per_side − 1), i = 0 … per_side − 1; the
    two points at a corner therefore differ in height (z_high vs z_low).
    With [1/3, 19/3], 10 per side and z in [1/30, 1/3]: 40 points spaced 2/3 m
    with z = (i + 1)/30 — the paper's static landmarks (SPEC 8.4).
    Returns shape (4·per_side, 3).
    """
    s = np.linspace(low, high, per_side)
    z = np.linspace(z_low, z_high, per_side)
    lo = np.full(per_side, low)
    hi = np.full(per_side, high)
    sides = [(s, lo), (hi, s), (s[::-1], hi), (lo, s[::-1])]
    return np.vstack([np.column_stack([x, y, z]) for x, y in sides])


def keyframe_profile(keyframes, n_frames: int) -> np.ndarray:
    """q per frame from ``keyframes`` [(frame, q), …] with cosine easing between them.

    Between keyframes (k_a, q_a) and (k_b, q_b):
    q = q_a + (q_b − q_a)·(1 − cos(π s))/2, s = (k − k_a)/(k_b − k_a), so the
    velocity is zero at every keyframe (a door starts and stops smoothly).
    Before the first keyframe q is the first value; after the last, the last.
    Returns shape (n_frames,).
    """
    frames = np.array([k for k, _ in keyframes], dtype=float)
    values = np.array([q for _, q in keyframes], dtype=float)
    k = np.arange(n_frames, dtype=float)
    q = np.full(n_frames, values[0])
    for i in range(len(frames) - 1):
        inside = (k >= frames[i]) & (k <= frames[i + 1])
        s = (k[inside] - frames[i]) / (frames[i + 1] - frames[i])
        q[inside] = values[i] + (values[i + 1] - values[i]) * 0.5 * (1.0 - np.cos(np.pi * s))
    q[k > frames[-1]] = values[-1]
    return q


def revolute_structure(centre, axis, zero_direction, radius: float) -> RevoluteStructure:
    """Circle of ``radius`` about ``centre`` in the plane normal to ``axis``.

    v1 = the part of ``zero_direction`` orthogonal to the axis, normalised (where
    φ = 0 points); v2 = â × v1, so φ turns right-handedly about the axis.
    """
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    v1 = np.asarray(zero_direction, dtype=float)
    v1 = v1 - (v1 @ a) * a
    v1 = v1 / np.linalg.norm(v1)
    v2 = np.cross(a, v1)
    return RevoluteStructure(p0=np.asarray(centre, dtype=float), v1=v1, v2=v2,
                             centre_xy=np.zeros(2), radius=float(radius), residual_m=0.0)

