"""Synthetic marker tracks of furniture joints (SPEC 10): doors, cabinet doors,
dishwasher doors and drawers moved by hand and seen by a motion-capture system.

Pure functions: a random generator in, arrays out; nothing is written here
(:mod:`stslam.io.track_files` writes tracks as text).

What varies from track to track (each drawn from ``rng``):

* geometry: hinge position and radius (door 0.5–0.9 m, cabinet door
  0.2–0.45 m, dishwasher door 0.4–0.6 m on a *horizontal* hinge 0.1 m above
  the floor), drawer direction and travel (0.15–0.5 m), marker height;
* the motion: a rest of 0.3–1.5 s before the motion starts (``onset_s``),
  a partial opening (door 30–110°, cabinet 40–120°, dishwasher 50–90°),
  pushed in one or two strokes with a pause of 0.3–1.5 s between them, and
  half of the time a partial or full closing after a hold; each stroke has a
  minimum-jerk profile whose time axis is warped by a slow random wobble, so
  the speed is hand-driven, not constant; stroke speeds 25–90°/s (doors) or
  0.1–0.4 m/s (drawers);
* noise: isotropic Gaussian, σ uniform in ``noise_range_m`` (default
  0.5–3 mm);
* the capture frame: a random yaw and, half of the time, y-up axes.

With a :class:`~stslam.sim.marker_camera.MarkerCamera` (``make_tracks.py
realistic=true``) the tracks are those of a camera-marker tracker instead:
its errors (:mod:`stslam.sim.marker_camera`), marker orientations, the
points in the camera frame, and :func:`realistic_ranges` of motion (rests up
to 4 s, pushes down to 0.4× speed with a stronger wobble, doors to 1 m,
drawers to 0.6 m, sliding doors of 0.3–0.8 m, top-hinged flaps).

Units: m, rad, s; points in the capture ("world") frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stslam.geometry import rotate_about_axis, rotation_z
from stslam.sim.marker_camera import MarkerCamera, marker_orientations, observe_markers

KINDS = ("door", "cabinet_door", "dishwasher", "drawer")
# The realistic set adds a sliding cabinet door (prismatic, up to 0.8 m) and a top-hinged
# flap (a horizontal hinge above the marker).
REALISTIC_KINDS = ("door", "cabinet_door", "dishwasher", "drawer", "sliding_door", "flap")
TRUE_MODEL = {"door": "revolute", "cabinet_door": "revolute", "dishwasher": "revolute",
              "drawer": "prismatic", "sliding_door": "prismatic", "flap": "revolute"}
# (low, high) of the opening: radians for hinged kinds, metres for drawers.
OPENING = {"door": np.radians([30.0, 110.0]), "cabinet_door": np.radians([40.0, 120.0]),
           "dishwasher": np.radians([50.0, 90.0]), "drawer": np.array([0.15, 0.5])}
SPEED = {"door": np.radians([25.0, 90.0]), "cabinet_door": np.radians([25.0, 90.0]),
         "dishwasher": np.radians([25.0, 90.0]), "drawer": np.array([0.1, 0.4])}
RADIUS_M = {"door": (0.5, 0.9), "cabinet_door": (0.2, 0.45), "dishwasher": (0.4, 0.6)}


@dataclass(frozen=True)
class MotionRanges:
    """How a hand uses a joint: ranges (low, high) of rests (s), speed factor and wobble.

    ``rest_s``: before the motion; ``pause_s``: between two strokes; ``hold_s``:
    before closing; ``end_s``: after the last stroke; ``speed_factor``: the kind's
    stroke speed is multiplied by it (< 1: slow pushes); ``wobble``: amplitude of
    the speed's wobble (< 1 keeps a stroke monotone); ``opening``, ``speed``,
    ``radius_m``: per kind, over :data:`OPENING`, :data:`SPEED`, :data:`RADIUS_M`.
    """

    rest_s: tuple[float, float] = (0.3, 1.5)
    pause_s: tuple[float, float] = (0.3, 1.5)
    hold_s: tuple[float, float] = (0.3, 1.0)
    end_s: tuple[float, float] = (0.2, 1.0)
    speed_factor: tuple[float, float] = (1.0, 1.0)
    wobble: tuple[float, float] = (0.0, 0.6)
    opening: dict = field(default_factory=lambda: dict(OPENING))
    speed: dict = field(default_factory=lambda: dict(SPEED))
    radius_m: dict = field(default_factory=lambda: dict(RADIUS_M))


def realistic_ranges() -> MotionRanges:
    """Long rests, slow and uneven pushes, radii from ~0.2 to 1 m, slides up to 0.6–0.8 m."""
    opening = dict(OPENING) | {"drawer": np.array([0.15, 0.6]), "sliding_door": np.array([0.3, 0.8]),
                               "flap": np.radians([50.0, 100.0])}
    speed = dict(SPEED) | {"sliding_door": SPEED["drawer"], "flap": SPEED["door"]}
    radius = dict(RADIUS_M) | {"door": (0.6, 1.0), "flap": (0.25, 0.4)}
    return MotionRanges(rest_s=(0.3, 4.0), pause_s=(0.3, 3.0), hold_s=(0.3, 3.0), end_s=(0.2, 3.0),
                        speed_factor=(0.4, 1.0), wobble=(0.0, 0.9), opening=opening, speed=speed,
                        radius_m=radius)


@dataclass(frozen=True)
class GeneratedTrack:
    """A synthetic track with its ground truth.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    true_model : str
        ``revolute`` or ``prismatic``.
    times_s : numpy.ndarray, shape (n,)
        Sample times from 0 (s).
    points_world : numpy.ndarray, shape (n, 3)
        Noisy marker positions (m, capture frame).
    onset_s : float
        Time at which the motion starts (s).
    noise_sigma_m : float
        Standard deviation of the noise on each coordinate (m).
    axis_direction, axis_point : numpy.ndarray, shape (3,)
        Hinge axis (unit vector) and a point on it (revolute); for a drawer the
        unit direction of travel and the closed position.
    radius_m : float
        Marker distance from the hinge axis (m); NaN for drawers.
    """

    kind: str
    true_model: str
    times_s: np.ndarray
    points_world: np.ndarray
    onset_s: float
    noise_sigma_m: float
    axis_direction: np.ndarray
    axis_point: np.ndarray
    radius_m: float
    orientations_xyzw: np.ndarray | None = None
    extra: dict = field(default_factory=dict)

    def metadata(self) -> dict[str, str]:
        """Ground truth as ``key: value`` text (written as ``#`` header lines of a track file)."""
        return {
            "kind": self.kind,
            "true_model": self.true_model,
            "onset_s": f"{self.onset_s:.4f}",
            "noise_sigma_m": f"{self.noise_sigma_m:.5f}",
            "axis_direction": " ".join(f"{v:.6f}" for v in self.axis_direction),
            "axis_point": " ".join(f"{v:.6f}" for v in self.axis_point),
            "radius_m": f"{self.radius_m:.5f}",
        } | dict(self.extra)


def minimum_jerk(u) -> np.ndarray:
    """Minimum-jerk fraction 10u³ − 15u⁴ + 6u⁵ of a stroke at normalised time u ∈ [0, 1]."""
    u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
    return u ** 3 * (10.0 - 15.0 * u + 6.0 * u * u)


def _warped_stroke(rng, n: int, wobble=(0.0, 0.6)) -> np.ndarray:
    """Stroke fraction at n evenly spaced instants, with a hand-like speed wobble."""
    u = np.linspace(0.0, 1.0, n)
    amplitude = rng.uniform(*wobble)  # < 1 keeps the warp monotone
    cycles = rng.uniform(1.0, 3.0)
    phase = rng.uniform(0, 2 * np.pi)
    warp = u + amplitude * (np.sin(2 * np.pi * cycles * u + phase) - np.sin(phase)) / (2 * np.pi * cycles)
    warp = (warp - warp[0]) / (warp[-1] - warp[0])
    return minimum_jerk(np.maximum.accumulate(warp))


def motion_profile(rng, kind: str, rate_hz: float,
                   ranges: MotionRanges | None = None) -> tuple[np.ndarray, np.ndarray, float]:
    """Joint coordinate over time for one hand-driven use of a ``kind`` of joint.

    Returns
    -------
    times_s : numpy.ndarray, shape (n,)
    joint : numpy.ndarray, shape (n,)
        Opening angle (rad) or drawer extension (m) from the closed position.
    onset_s : float
        Start of the first stroke (s).
    """
    g = ranges or MotionRanges()
    dt = 1.0 / rate_hz
    opening = rng.uniform(*g.opening[kind])
    pieces = [np.zeros(max(1, int(round(rng.uniform(*g.rest_s) / dt))))]
    onset_s = pieces[0].size * dt
    strokes = [opening] if rng.random() < 0.6 else [opening * rng.uniform(0.3, 0.7), opening]
    factor = 1.0 if ranges is None else rng.uniform(*g.speed_factor)
    level = 0.0
    for k, target in enumerate(strokes):
        if k > 0:
            pieces.append(np.full(int(round(rng.uniform(*g.pause_s) / dt)), level))
        duration = abs(target - level) / (rng.uniform(*g.speed[kind]) * factor)
        n = max(3, int(round(duration / dt)))
        pieces.append(level + (target - level) * _warped_stroke(rng, n + 1, g.wobble)[1:])
        level = target
    if rng.random() < 0.5:  # hold, then close part of the way or fully
        pieces.append(np.full(int(round(rng.uniform(*g.hold_s) / dt)), level))
        target = level * (1.0 - rng.uniform(0.3, 1.0))
        n = max(3, int(round(abs(level - target) / (rng.uniform(*g.speed[kind]) * factor) / dt)))
        pieces.append(level + (target - level) * _warped_stroke(rng, n + 1, g.wobble)[1:])
        level = target
    pieces.append(np.full(int(round(rng.uniform(*g.end_s) / dt)), level))
    joint = np.concatenate(pieces)
    return np.arange(joint.size) * dt, joint, onset_s


def _capture_frame(rng) -> np.ndarray:
    """Rotation from the room frame (z up) to the capture frame: random yaw, y-up half of the time."""
    R = rotation_z(rng.uniform(-np.pi, np.pi))
    if rng.random() < 0.5:
        R = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]) @ R  # z up → y up
    return R


def _true_points(rng, kind: str, joint: np.ndarray, ranges: MotionRanges | None):
    """True marker positions (n, 3) in the room frame (z up), with axis, axis point and radius."""
    heading = rng.uniform(-np.pi, np.pi)
    along = np.array([np.cos(heading), np.sin(heading), 0.0])  # horizontal, room frame
    base = np.array([rng.uniform(-2, 2), rng.uniform(-2, 2), 0.0])
    if TRUE_MODEL[kind] == "prismatic":
        closed = base + np.array([0.0, 0.0, rng.uniform(0.2, 1.0) if kind == "drawer" else rng.uniform(0.5, 1.8)])
        return closed + joint[:, None] * along, along, closed, float("nan")
    radius = rng.uniform(*(ranges or MotionRanges()).radius_m[kind])
    sense = rng.choice([-1.0, 1.0])  # which way the door swings
    if kind == "dishwasher":
        axis = np.cross(along, [0.0, 0.0, 1.0])  # horizontal hinge
        hinge = base + np.array([0.0, 0.0, 0.1])
        closed_offset = np.array([0.0, 0.0, radius])  # door upright when closed
    elif kind == "flap":
        axis = np.cross(along, [0.0, 0.0, 1.0])  # horizontal hinge above the marker
        hinge = base + np.array([0.0, 0.0, rng.uniform(0.6, 2.0)])
        closed_offset = np.array([0.0, 0.0, -radius])
    else:
        axis = np.array([0.0, 0.0, 1.0])
        hinge = base + np.array([0.0, 0.0, rng.uniform(0.3, 1.2)])
        closed_offset = radius * along
    points = hinge + rotate_about_axis(closed_offset, axis, sense * joint)
    return points, axis * sense, hinge, float(radius)


def generate_track(rng, kind: str, rate_hz: float = 30.0,
                   noise_range_m: tuple[float, float] = (0.0005, 0.003),
                   camera: MarkerCamera | None = None) -> GeneratedTrack:
    """One synthetic track of a ``kind`` of joint (see the module docstring).

    With ``camera`` the track is realistic: :func:`realistic_ranges` of motion,
    seen by a camera-marker tracker (:mod:`stslam.sim.marker_camera`; points in
    the camera frame, ``noise_range_m`` unused) with marker orientations.
    """
    kinds = KINDS if camera is None else REALISTIC_KINDS
    if kind not in kinds:
        raise ValueError(f"kind must be one of {', '.join(kinds)}, got {kind!r}")
    ranges = None if camera is None else realistic_ranges()
    times, joint, onset = motion_profile(rng, kind, rate_hz, ranges)
    points, axis_direction, axis_point, radius = _true_points(rng, kind, joint, ranges)
    if camera is not None:
        observed, times, kept, (R, centre), info = observe_markers(rng, points, times, camera)
        axis = None if TRUE_MODEL[kind] == "prismatic" else R @ axis_direction
        quaternions = marker_orientations(rng, observed, axis)
        return GeneratedTrack(kind=kind, true_model=TRUE_MODEL[kind], times_s=times, points_world=observed,
                              onset_s=float(onset), noise_sigma_m=float(info.pop("camera_sigma0_m")),
                              axis_direction=R @ axis_direction, axis_point=R @ (axis_point - centre),
                              radius_m=radius, orientations_xyzw=quaternions, extra=info)
    R = _capture_frame(rng)
    sigma = rng.uniform(*noise_range_m)
    noisy = points @ R.T + rng.normal(0.0, sigma, points.shape)
    return GeneratedTrack(kind=kind, true_model=TRUE_MODEL[kind], times_s=times, points_world=noisy,
                          onset_s=float(onset), noise_sigma_m=float(sigma),
                          axis_direction=R @ axis_direction, axis_point=R @ axis_point,
                          radius_m=float(radius))


def generate_tracks(n: int, seed: int, kinds=None, rate_hz: float = 30.0,
                    noise_range_m: tuple[float, float] = (0.0005, 0.003),
                    camera: MarkerCamera | None = None) -> list[GeneratedTrack]:
    """``n`` tracks cycling through ``kinds``; track i draws from ``default_rng(seed + i)``.

    ``kinds`` defaults to :data:`KINDS`, or :data:`REALISTIC_KINDS` with a ``camera``.
    """
    kinds = kinds or (KINDS if camera is None else REALISTIC_KINDS)
    return [generate_track(np.random.default_rng(seed + i), kinds[i % len(kinds)], rate_hz, noise_range_m, camera)
            for i in range(n)]
