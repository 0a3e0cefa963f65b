"""Simulated worlds: landmarks with their true articulation and a robot path (SPEC 8.4).

A world is built from a plain config dict (``conf/world/<name>.yaml``). Every
landmark carries its *true* model, structure and motion variable q per frame;
its position is f(C, q) from :mod:`stslam.articulation.models`, so an oracle that is
handed (model, structure) explains the landmark exactly.

Units: metres, radians; times in frames (frame k is at time k·δt seconds).

Config keys (all under ``world``)::

    name, n_frames, dt, alpha: [α1, α2, α3, α4]
    robot:            {type: circle, centre: [x, y], radius, start_angle, angle_step}
                   or {type: segments, start: [x, y, θ], segments: [[v, ω, frames], …]}
    static_square:    {low, high, per_side, z_low, z_high}      (optional)
    static_points:    [[x, y, z], …]                              (optional)
    landmarks:        articulated (or single static) landmarks     (optional)
      - {name, model: prismatic, origin: [..], direction: [..], motion: …}
      - {name, model: revolute, centre: [..], axis: [..], zero_direction: [..],
         radius, motion: …}
      - {name, model: static, origin: [..]}
    motion: {start, rate}                 q(k) = start + rate·k
         or {keyframes: [[frame, q], …]}  smooth (cosine) easing between
                                          keyframes, constant outside them
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from stslam.articulation.models import (PrismaticStructure, RevoluteStructure, StaticStructure,
                                 get_model)
from stslam.errors import ConfigError
from stslam.config.readers import get_float, get_float_list, get_int, lookup
from stslam.robot.motion import check_alpha, move


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
    """

    name: str
    model_name: str
    structure: object
    q: np.ndarray

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


# ---------------------------------------------------------------- config reading

def _prefixed(prefix: str, fn, *args, **kwargs):
    """Call a :mod:`stslam.config.readers` getter; re-raise its ConfigError with ``prefix`` on the key."""
    try:
        return fn(*args, **kwargs)
    except ConfigError as error:
        raise ConfigError(f"{prefix}{error}") from None


def _numbers(key: str, value, length: int) -> list[float]:
    """``value`` as a list of ``length`` finite floats; ConfigError naming ``key`` otherwise."""
    ok = isinstance(value, (list, tuple)) and len(value) == length and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) for v in value)
    if not ok:
        raise ConfigError(f"{key}: expected a list of {length} numbers, got {value!r}")
    return [float(v) for v in value]


def _unit(prefix: str, cfg: Mapping, key: str) -> np.ndarray:
    v = np.array(_prefixed(prefix, get_float_list, cfg, key, length=3))
    norm = float(np.linalg.norm(v))
    if norm < 1e-12:
        raise ConfigError(f"{prefix}{key}: expected a non-zero direction, got {v.tolist()}")
    return v / norm


def _motion(prefix: str, cfg: Mapping, n_frames: int) -> np.ndarray:
    motion = lookup(cfg, "motion", None)
    if not isinstance(motion, Mapping):
        raise ConfigError(f"{prefix}motion: expected {{start, rate}} or {{keyframes}}, got {motion!r}")
    if "keyframes" in motion:
        frames = motion["keyframes"]
        if not isinstance(frames, list) or len(frames) < 1:
            raise ConfigError(f"{prefix}motion.keyframes: expected a list of [frame, q], got {frames!r}")
        keyframes = []
        for i, item in enumerate(frames):
            pair = _numbers(f"{prefix}motion.keyframes[{i}]", item, 2)
            if keyframes and pair[0] <= keyframes[-1][0]:
                raise ConfigError(f"{prefix}motion.keyframes[{i}]: frames must increase, got {pair[0]!r}")
            keyframes.append(pair)
        return keyframe_profile(keyframes, n_frames)
    start = _prefixed(prefix + "motion.", get_float, motion, "start")
    rate = _prefixed(prefix + "motion.", get_float, motion, "rate")
    return start + rate * np.arange(n_frames, dtype=float)


def _landmark(prefix: str, cfg: Mapping, n_frames: int) -> LandmarkTruth:
    if not isinstance(cfg, Mapping):
        raise ConfigError(f"{prefix[:-1]}: expected a mapping, got {cfg!r}")
    name = str(lookup(cfg, "name", prefix.rstrip(".")))
    kind = lookup(cfg, "model", None)
    if kind == "static":
        p0 = np.array(_prefixed(prefix, get_float_list, cfg, "origin", length=3))
        return LandmarkTruth(name, "static", StaticStructure(p0=p0, residual_m=0.0), np.zeros((n_frames, 1)))
    if kind == "prismatic":
        structure = PrismaticStructure(p0=np.array(_prefixed(prefix, get_float_list, cfg, "origin", length=3)),
                                       direction=_unit(prefix, cfg, "direction"), residual_m=0.0)
    elif kind == "revolute":
        axis = _unit(prefix, cfg, "axis")
        zero = _unit(prefix, cfg, "zero_direction")
        if abs(float(axis @ zero)) > 1.0 - 1e-9:
            raise ConfigError(f"{prefix}zero_direction: must not be parallel to the axis")
        structure = revolute_structure(_prefixed(prefix, get_float_list, cfg, "centre", length=3), axis, zero,
                                       _prefixed(prefix, get_float, cfg, "radius", low=0.0, low_open=True))
    else:
        raise ConfigError(f"{prefix}model: expected one of static, prismatic, revolute; got {kind!r}")
    return LandmarkTruth(name, kind, structure, _motion(prefix, cfg, n_frames).reshape(-1, 1))


def _robot_path(cfg: Mapping, n_frames: int, dt: float) -> np.ndarray:
    kind = lookup(cfg, "world.robot.type")
    if kind == "circle":
        centre = get_float_list(cfg, "world.robot.centre", length=2)
        path = circle_path(centre, get_float(cfg, "world.robot.radius", low=0.0, low_open=True),
                           get_float(cfg, "world.robot.start_angle"),
                           get_float(cfg, "world.robot.angle_step"), n_frames)
        return path
    if kind == "segments":
        start = get_float_list(cfg, "world.robot.start", length=3)
        segments = lookup(cfg, "world.robot.segments")
        if not isinstance(segments, list) or not segments:
            raise ConfigError(f"world.robot.segments: expected a list of [v, ω, frames], got {segments!r}")
        parsed = []
        for i, item in enumerate(segments):
            seg = _numbers(f"world.robot.segments[{i}]", item, 3)
            if seg[2] < 0 or not seg[2].is_integer():
                raise ConfigError(f"world.robot.segments[{i}]: expected [v, ω, frames ≥ 0], got {item!r}")
            parsed.append(seg)
        path = segments_path(start, parsed, dt)
        if path.shape[0] < n_frames:
            raise ConfigError(f"world.robot.segments: cover {path.shape[0]} frames, need n_frames = {n_frames}")
        return path[:n_frames]
    raise ConfigError(f"world.robot.type: expected one of circle, segments; got {kind!r}")


def world_from_config(cfg: Mapping) -> World:
    """Build the world of ``cfg["world"]``; ConfigError naming the key for any bad value."""
    n_frames = get_int(cfg, "world.n_frames", low=2)
    dt = get_float(cfg, "world.dt", low=0.0, low_open=True)
    alpha = check_alpha(get_float_list(cfg, "world.alpha", length=4, low=0.0))
    landmarks: list[LandmarkTruth] = []
    square = lookup(cfg, "world.static_square", None)
    points = []
    if square is not None:
        per_side = get_int(cfg, "world.static_square.per_side", low=2)
        points.append(square_perimeter_points(
            get_float(cfg, "world.static_square.low"), get_float(cfg, "world.static_square.high"), per_side,
            get_float(cfg, "world.static_square.z_low"), get_float(cfg, "world.static_square.z_high")))
    extra = lookup(cfg, "world.static_points", None)
    if extra is not None:
        if not isinstance(extra, list):
            raise ConfigError(f"world.static_points: expected a list of [x, y, z], got {extra!r}")
        points.append(np.array([_numbers(f"world.static_points[{i}]", p, 3) for i, p in enumerate(extra)])
                      .reshape(-1, 3))
    for i, p0 in enumerate(np.vstack(points) if points else np.zeros((0, 3))):
        landmarks.append(LandmarkTruth(f"static_{i:02d}", "static", StaticStructure(p0=p0, residual_m=0.0),
                                       np.zeros((n_frames, 1))))
    listed = lookup(cfg, "world.landmarks", None) or []
    if not isinstance(listed, list):
        raise ConfigError(f"world.landmarks: expected a list, got {listed!r}")
    for i, item in enumerate(listed):
        landmarks.append(_landmark(f"world.landmarks[{i}].", item, n_frames))
    if not landmarks:
        raise ConfigError("world: no landmarks (give static_square, static_points or landmarks)")
    names = [lm.name for lm in landmarks]
    if len(set(names)) != len(names):
        raise ConfigError(f"world.landmarks: names must be unique, got {names}")
    poses = _robot_path(cfg, n_frames, dt)
    positions = np.stack([lm.positions() for lm in landmarks], axis=1)
    return World(name=str(lookup(cfg, "world.name", "world")), dt=dt, alpha=alpha, poses_xytheta=poses,
                 landmarks=tuple(landmarks), positions=positions)
