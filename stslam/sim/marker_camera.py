"""A camera-based marker tracker's errors, applied to true marker positions (SPEC 10).

Fiducial markers tracked by one camera at ~30 Hz err in ways a motion-capture
system does not; :func:`observe_markers` reproduces the ones that fool a
model selector:

* noise that grows with depth: along the viewing ray σ_d = σ₀ + c·z² (the
  depth of a marker comes from its apparent size, so its error grows like
  z²), across it σ₀ + σ₀·z (pixel noise scaled by depth);
* a depth bias that bends straight paths: the depth is off by
  z·(β₀ + β₂·ρ²), with ρ² = (x² + y²)/z² the squared distance from the
  optical axis in normalised image coordinates (a residual of the lens and
  marker-size calibration). A slide that crosses the image is seen on a
  curve: a 0.6 m travel at 1 m with β₂ = 0.3 bows by about 3 cm;
* outliers (a marker corner mis-detected: one sample off by 2–20 cm) and
  jumps (a pose flip or a re-detection: the position is offset by 1–5 cm for
  a short burst);
* dropouts: bursts of samples missing (the marker occluded by a hand or seen
  edge-on).

The camera stands 1–3 m from the joint, looking at it with a small random
offset. Pure functions: ``rng`` in, arrays out. Units: m, s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class MarkerCamera:
    """Ranges (low, high) each track draws its camera errors from (module docstring).

    ``sigma0_m``: base noise (m); ``depth_coeff``: c in σ_d = σ₀ + c·z² (1/m);
    ``bias_scale``: |β₀|; ``bias_radial``: |β₂| (a random sign each);
    ``distance_m``: camera to joint; ``outlier_rate``, ``jump_rate``,
    ``dropout_rate``: events per second; ``jump_m``, ``jump_s``: jump size
    and duration; ``dropout_s``: length of a dropout burst.
    """

    sigma0_m: tuple[float, float] = (0.0005, 0.002)
    depth_coeff: tuple[float, float] = (0.0005, 0.002)
    bias_scale: tuple[float, float] = (0.0, 0.02)
    bias_radial: tuple[float, float] = (0.0, 0.35)
    distance_m: tuple[float, float] = (1.0, 3.0)
    outlier_rate: float = 0.3
    outlier_m: tuple[float, float] = (0.02, 0.2)
    jump_rate: float = 0.05
    jump_m: tuple[float, float] = (0.01, 0.05)
    jump_s: tuple[float, float] = (0.1, 0.5)
    dropout_rate: float = 0.1
    dropout_s: tuple[float, float] = (0.1, 1.0)


def camera_pose(rng, target_world: np.ndarray, distance_range_m) -> tuple[np.ndarray, np.ndarray]:
    """Rotation R (camera ← world) and camera centre c (3,) looking roughly at ``target_world``."""
    azimuth = rng.uniform(-np.pi, np.pi)
    elevation = rng.uniform(np.radians(-10.0), np.radians(40.0))
    distance = rng.uniform(*distance_range_m)
    back = np.array([np.cos(elevation) * np.cos(azimuth), np.cos(elevation) * np.sin(azimuth), np.sin(elevation)])
    centre = target_world + distance * back
    aim = target_world + rng.normal(0.0, 0.1, 3) - centre
    forward = aim / np.linalg.norm(aim)  # camera z: viewing direction
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    return np.vstack([right, down, forward]), centre


def observe_markers(rng, points_world, times_s, camera: MarkerCamera):
    """Camera-marker observations of true positions (n, 3) at ``times_s`` (n,).

    Returns the observed points (m, 3) in the camera frame and their times
    (m,) (dropouts removed), the kept indices (m,), the pose (R camera ← world,
    camera centre) and a dict of the drawn camera parameters (for the file header).
    """
    points = np.asarray(points_world, dtype=float)
    times = np.asarray(times_s, dtype=float)
    n = points.shape[0]
    dt = float(np.median(np.diff(times))) if n > 1 else 1.0
    R, centre = camera_pose(rng, points.mean(axis=0), camera.distance_m)
    p_cam = (points - centre) @ R.T
    z = p_cam[:, 2]
    sigma0 = rng.uniform(*camera.sigma0_m)
    depth_coeff = rng.uniform(*camera.depth_coeff)
    beta0 = rng.uniform(*camera.bias_scale) * rng.choice([-1.0, 1.0])
    beta2 = rng.uniform(*camera.bias_radial) * rng.choice([-1.0, 1.0])
    rho2 = (p_cam[:, 0] ** 2 + p_cam[:, 1] ** 2) / z ** 2
    scale = 1.0 + beta0 + beta2 * rho2  # depth bias along the ray: (x, y, z) ∝ z
    sigma_depth = sigma0 + depth_coeff * z ** 2
    sigma_across = sigma0 * (1.0 + z)
    ray = p_cam / np.linalg.norm(p_cam, axis=1, keepdims=True)
    noisy = p_cam * scale[:, None] + ray * rng.normal(0.0, 1.0, n)[:, None] * sigma_depth[:, None]
    noisy[:, :2] += rng.normal(0.0, 1.0, (n, 2)) * sigma_across[:, None]
    duration = n * dt
    for _ in range(rng.poisson(camera.outlier_rate * duration)):
        i = rng.integers(n)
        direction = rng.normal(size=3)
        noisy[i] += rng.uniform(*camera.outlier_m) * direction / np.linalg.norm(direction)
    for _ in range(rng.poisson(camera.jump_rate * duration)):
        i = rng.integers(n)
        length = max(1, int(round(rng.uniform(*camera.jump_s) / dt)))
        direction = rng.normal(size=3)
        noisy[i:i + length] += rng.uniform(*camera.jump_m) * direction / np.linalg.norm(direction)
    keep = np.ones(n, dtype=bool)
    for _ in range(rng.poisson(camera.dropout_rate * duration)):
        i = rng.integers(n)
        keep[i:i + max(1, int(round(rng.uniform(*camera.dropout_s) / dt)))] = False
    keep[:3] = True  # a track starts with an observation
    info = {"camera_sigma0_m": f"{sigma0:.5f}", "camera_depth_coeff": f"{depth_coeff:.5f}",
            "camera_bias": f"{beta0:.4f} {beta2:.4f}", "camera_distance_m": f"{float(np.median(z)):.3f}"}
    kept = np.flatnonzero(keep)
    return noisy[kept], times[kept], kept, (R, centre), info


def marker_orientations(rng, points_world, axis_unit=None) -> np.ndarray:
    """Unit quaternions (n, 4) x, y, z, w of a marker on the moving part (written, not used).

    A fixed random orientation turned about ``axis_unit`` by the angle swept
    around it (revolute), or constant (``axis_unit`` None), plus a little jitter.
    """
    n = np.asarray(points_world).shape[0]
    q0 = rng.normal(size=4)
    q0 /= np.linalg.norm(q0)
    if axis_unit is None:
        q = np.tile(q0, (n, 1))
    else:
        p = np.asarray(points_world, dtype=float)
        c = p - p.mean(axis=0)
        angle = np.unwrap(np.arctan2(c @ np.cross(axis_unit, c[0] / max(np.linalg.norm(c[0]), 1e-9)),
                                     c @ (c[0] / max(np.linalg.norm(c[0]), 1e-9))))
        half = 0.5 * (angle - angle[0])
        turn = np.column_stack([np.sin(half)[:, None] * np.asarray(axis_unit)[None, :], np.cos(half)])
        x1, y1, z1, w1 = turn.T
        x2, y2, z2, w2 = q0
        q = np.column_stack([w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2, w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                             w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2, w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2])
    q = q + rng.normal(0.0, 0.005, q.shape)
    return q / np.linalg.norm(q, axis=1, keepdims=True)
