"""Simulated worlds and door traces from their config blocks (SPEC 8.2, 8.4).

``world`` (``conf/world/<name>.yaml``) gives a :class:`~stslam.sim.worlds.World`::

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
      - a rigid part carrying several points (SPEC 13): the same entries with
        ``points: [[x, y, z], …]``, the points' positions at q = 0; each becomes
        a landmark ``<name>_<i>`` of the part (``LandmarkTruth.body``) with the
        part's motion: prismatic, origin = the point, along ``direction``;
        revolute about the axis through ``centre`` along ``axis`` (radius and
        zero_direction then come from each point)
    motion: {start, rate}                 q(k) = start + rate·k
         or {keyframes: [[frame, q], …]}  smooth (cosine) easing between
                                          keyframes, constant outside them

``door`` (``conf/exp/temporal_order.yaml``) gives a
:class:`~stslam.sim.door_trace.DoorScenario`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from stslam.articulation.models import PrismaticStructure, StaticStructure
from stslam.config.readers import get_float, get_float_list, get_int, lookup
from stslam.errors import ConfigError
from stslam.robot.motion import check_alpha
from stslam.sim.door_trace import DoorModel, DoorScenario, Push, PushJitter
from stslam.sim.worlds import (LandmarkTruth, World, circle_path, keyframe_profile, revolute_structure,
                               segments_path, square_perimeter_points)


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


def _landmark(prefix: str, cfg: Mapping, n_frames: int) -> list[LandmarkTruth]:
    """The landmark(s) of one ``world.landmarks`` entry: one, or one per point of a rigid part."""
    if not isinstance(cfg, Mapping):
        raise ConfigError(f"{prefix[:-1]}: expected a mapping, got {cfg!r}")
    name = str(lookup(cfg, "name", prefix.rstrip(".")))
    kind = lookup(cfg, "model", None)
    if kind == "static":
        p0 = np.array(_prefixed(prefix, get_float_list, cfg, "origin", length=3))
        return [LandmarkTruth(name, "static", StaticStructure(p0=p0, residual_m=0.0), np.zeros((n_frames, 1)))]
    if kind not in ("prismatic", "revolute"):
        raise ConfigError(f"{prefix}model: expected one of static, prismatic, revolute; got {kind!r}")
    points = lookup(cfg, "points", None)
    if points is not None:
        if not isinstance(points, list) or not points:
            raise ConfigError(f"{prefix}points: expected a list of [x, y, z], got {points!r}")
        q = _motion(prefix, cfg, n_frames).reshape(-1, 1)
        members = [np.array(_numbers(f"{prefix}points[{i}]", p, 3)) for i, p in enumerate(points)]
        return [LandmarkTruth(f"{name}_{i}", kind, _part_structure(f"{prefix}points[{i}]", prefix, cfg, kind, p),
                              q, body=name) for i, p in enumerate(members)]
    if kind == "prismatic":
        structure = PrismaticStructure(p0=np.array(_prefixed(prefix, get_float_list, cfg, "origin", length=3)),
                                       direction=_unit(prefix, cfg, "direction"), residual_m=0.0)
    else:
        axis = _unit(prefix, cfg, "axis")
        zero = _unit(prefix, cfg, "zero_direction")
        if abs(float(axis @ zero)) > 1.0 - 1e-9:
            raise ConfigError(f"{prefix}zero_direction: must not be parallel to the axis")
        structure = revolute_structure(_prefixed(prefix, get_float_list, cfg, "centre", length=3), axis, zero,
                                       _prefixed(prefix, get_float, cfg, "radius", low=0.0, low_open=True))
    return [LandmarkTruth(name, kind, structure, _motion(prefix, cfg, n_frames).reshape(-1, 1))]


def _part_structure(key: str, prefix: str, cfg: Mapping, kind: str, point: np.ndarray):
    """Structure of one point of a rigid part (SPEC 13): its own line or circle, sharing the part's q.

    Prismatic: p(l) = p_ref + l·n̂. Revolute: p(φ) = a + R(axis, φ)(p_ref − a), the
    circle about the axis through p_ref: centre the foot of p_ref on the axis,
    v1 towards p_ref (φ = 0 there), radius the distance to the axis.
    """
    if kind == "prismatic":
        return PrismaticStructure(p0=point, direction=_unit(prefix, cfg, "direction"), residual_m=0.0)
    axis = _unit(prefix, cfg, "axis")
    a = np.array(_prefixed(prefix, get_float_list, cfg, "centre", length=3))
    foot = a + ((point - a) @ axis) * axis
    radius = float(np.linalg.norm(point - foot))
    if radius < 1e-6:
        raise ConfigError(f"{key}: expected a point off the hinge axis, got {point.tolist()}")
    return revolute_structure(foot, axis, point - foot, radius)


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
    """The :class:`~stslam.sim.worlds.World` of the ``world`` block; ConfigError naming the key of any bad value."""
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
        landmarks.extend(_landmark(f"world.landmarks[{i}].", item, n_frames))
    if not landmarks:
        raise ConfigError("world: no landmarks (give static_square, static_points or landmarks)")
    names = [lm.name for lm in landmarks]
    if len(set(names)) != len(names):
        raise ConfigError(f"world.landmarks: names must be unique, got {names}")
    poses = _robot_path(cfg, n_frames, dt)
    positions = np.stack([lm.positions() for lm in landmarks], axis=1)
    return World(name=str(lookup(cfg, "world.name", "world")), dt=dt, alpha=alpha, poses_xytheta=poses,
                 landmarks=tuple(landmarks), positions=positions)


def door_scenario_from_config(cfg: Mapping, prefix: str = "door") -> DoorScenario:
    """Checked :class:`~stslam.sim.door_trace.DoorScenario` from the keys under ``prefix`` (ConfigError)."""
    key = prefix + "."
    closed = get_float(cfg, key + "closed_angle")
    spring = get_float(cfg, key + "spring_rest_angle")
    if spring > closed:
        raise ConfigError(f"{key}spring_rest_angle: expected ≤ {key}closed_angle = {closed} "
                          f"(the spring must hold the door shut), got {spring!r}")
    model = DoorModel(
        closed_angle=closed,
        spring_rest_angle=spring,
        natural_freq=get_float(cfg, key + "natural_freq", low=0, low_open=True),
        damping_ratio=get_float(cfg, key + "damping_ratio", low=0),
        restitution=get_float(cfg, key + "restitution", low=0, high=1),
    )
    times = get_float_list(cfg, key + "push_times", low=0)
    accels = get_float_list(cfg, key + "push_accel", length=len(times), low=0)
    releases = get_float_list(cfg, key + "release_angle", length=len(times))
    for i, release in enumerate(releases):
        if release <= closed:
            raise ConfigError(f"{key}release_angle[{i}]: expected > {key}closed_angle = {closed}, "
                              f"got {release!r}")
    max_s = get_float(cfg, key + "push_max_s", low=0, low_open=True)
    step_s = get_float(cfg, key + "step_s", low=0, low_open=True)
    return DoorScenario(
        model=model,
        pushes=tuple(Push(t, a, r, max_s) for t, a, r in zip(times, accels, releases)),
        n_samples=get_int(cfg, key + "n_samples", low=2),
        noise_sigma=get_float(cfg, key + "noise_sigma", low=0),
        step_s=step_s,
        jitter=PushJitter(time_s=get_float(cfg, key + "jitter.time_s", low=0),
                          accel_frac=get_float(cfg, key + "jitter.accel_frac", low=0, high=1),
                          release_rad=get_float(cfg, key + "jitter.release_rad", low=0)),
    )
