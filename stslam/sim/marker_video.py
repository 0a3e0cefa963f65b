"""Rendered videos of a fiducial marker on a turning door or a sliding drawer, with known truth (SPEC 17).

World frame: x to the right, y away from the camera, z up (m). The wall is the
plane y = 0.02 m. A door's hinge passes through the origin along z tilted by
``axis_tilt_deg`` about y; its panel (x ≥ 0 when closed) turns towards the
camera by the angle φ(t). A drawer front (x ∈ [0, 0.5] m, in the plane y = 0)
slides along −y tilted by ``axis_tilt_deg`` about z, by l(t). φ and l rest,
move with a smooth (cosine) profile over the middle ``move_fraction`` of the
video, and rest again.

Each frame is drawn as the ideal pinhole image of textured planes (painted far
to near, supersampled ``supersample`` times and averaged down), moved through
the lens distortion (every recorded pixel takes the ideal image at its
undistorted position), blurred by averaging ``blur_samples`` instants over
``exposure_frames`` of motion and a Gaussian of ``blur_px``, and given pixel
noise of ``noise_grey`` grey levels. Everything follows from ``seed``.

Truth is given in the frame the poses are reported in: the camera's (a static
camera) or, with a reference marker on the wall, the reference marker's
(OpenCV's marker frame: :mod:`stslam.markers.pose`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stslam.checks import check_choice
from stslam.geometry import invert_pose, pose_matrix, rotation_about_axis
from stslam.markers.detect import dictionary

WALL_Y_M = 0.02


@dataclass(frozen=True)
class MarkerVideoScene:
    """What a rendered marker video shows; lengths in m, angles in degrees (module docstring)."""

    kind: str = "door"                  # door | drawer
    width: int = 320
    height: int = 240
    n_frames: int = 90
    fps: float = 30.0
    focal_px: float = 300.0
    distortion: tuple = (-0.25, 0.08, 0.001, -0.001, 0.0)  # OpenCV's k1 k2 p1 p2 k3
    marker_length_m: float = 0.15
    marker_id: int = 7
    dictionary: str = "DICT_6X6_250"
    marker_offset_m: float = 0.55       # door: hinge to marker centre; drawer: x of the marker (front's centre)
    marker_height_m: float = 1.0        # height of the marker centre
    axis_tilt_deg: float = 2.0
    start: float = 5.0                  # door: φ at rest before (deg); drawer: l (m)
    end: float = 75.0                   # door: φ after (deg); drawer: l (m)
    move_fraction: float = 0.7
    camera_position_m: tuple = (-0.7, -1.4, 1.35)  # door: on the hinge's side, so the opening door faces it
    camera_target_m: tuple = (0.3, -0.3, 1.0)
    camera_shake_m: float = 0.0         # a hand-held camera: amplitude of its wandering (m); its turn follows
    reference_id: int | None = None     # a second marker on the wall (the fixed part)
    reference_position_m: tuple = (-0.22, 1.15)  # its (x, z) on the wall
    supersample: int = 2
    exposure_frames: float = 0.5
    blur_samples: int = 2
    blur_px: float = 0.6
    noise_grey: float = 2.0
    seed: int = 0


def _look_at(position, target) -> np.ndarray:
    """T_world_camera (4, 4) of a camera at ``position`` looking at ``target`` (x right, y down, z forward)."""
    z = np.asarray(target, float) - np.asarray(position, float)
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return pose_matrix(np.column_stack([x, np.cross(z, x), z]), position)


def _plane(origin, u, v, size_m, texture) -> tuple:
    """A textured rectangle: corner ``origin``, unit directions u (texture columns) and v (rows), size (m)."""
    return np.asarray(origin, float), np.asarray(u, float), np.asarray(v, float), size_m, texture


def _tiles(origin, u, v, size_m, texture, n: int) -> list:
    """The rectangle of :func:`_plane` cut into n × n tiles (a tile behind the camera is left out, not the wall)."""
    origin, u, v = (np.asarray(x, float) for x in (origin, u, v))
    rows, cols = texture.shape[:2]
    out = []
    for a in range(n):
        for b in range(n):
            i0, i1, j0, j1 = rows * a // n, rows * (a + 1) // n, cols * b // n, cols * (b + 1) // n
            corner = origin + (j0 / cols) * size_m[0] * u + (i0 / rows) * size_m[1] * v
            out.append(_plane(corner, u, v, ((j1 - j0) / cols * size_m[0], (i1 - i0) / rows * size_m[1]),
                              texture[i0:i1, j0:j1]))
    return out


class MarkerVideoRenderer:
    """Frames and truth of a :class:`MarkerVideoScene`."""

    def __init__(self, scene: MarkerVideoScene):
        check_choice("kind", scene.kind, ("door", "drawer"))
        self.scene = s = scene
        rng = np.random.default_rng(s.seed)
        self.K = np.array([[s.focal_px, 0.0, (s.width - 1) / 2], [0.0, s.focal_px, (s.height - 1) / 2],
                           [0.0, 0.0, 1.0]])
        self.D = np.asarray(s.distortion, dtype=float)
        self._noise_rng = np.random.default_rng(s.seed + 1)
        grey = rng.integers(110, 190, (48, 72, 1))
        self._wall = np.clip(grey + rng.integers(-8, 8, (48, 72, 3)), 0, 255).astype(np.uint8)
        self._wall = cv2.resize(self._wall, (384, 256), interpolation=cv2.INTER_CUBIC)
        self._panel = np.clip(np.array([175, 195, 215]) + rng.normal(0, 6, (80, 60, 3)), 0, 255).astype(np.uint8)
        self._marker = self._marker_texture(s.marker_id)
        self._reference = None if s.reference_id is None else self._marker_texture(s.reference_id)
        self._shake = rng.uniform(0, 2 * np.pi, (2, 3)), rng.uniform(0.3, 0.9, (2, 3))
        tilt = np.radians(s.axis_tilt_deg)
        self.axis_world = (np.array([np.sin(tilt), 0.0, np.cos(tilt)]) if s.kind == "door"
                           else np.array([np.sin(tilt), -np.cos(tilt), 0.0]))
        self._margin, self._maps = self._distortion_maps()

    def _marker_texture(self, marker_id: int) -> np.ndarray:
        cells = 8
        image = cv2.aruco.generateImageMarker(dictionary(self.scene.dictionary), int(marker_id), 20 * cells)
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)

    def _distortion_maps(self):
        """Where each recorded pixel's ray meets the ideal image (with a margin around it), for cv2.remap."""
        s = self.scene
        u, v = np.meshgrid(np.arange(s.width, dtype=np.float64), np.arange(s.height, dtype=np.float64))
        pixels = np.stack([u.ravel(), v.ravel()], axis=1).reshape(-1, 1, 2)
        ideal = cv2.undistortPoints(pixels, self.K, self.D, P=self.K).reshape(s.height, s.width, 2)
        margin = int(np.ceil(max(0.0, -ideal[..., 0].min(), -ideal[..., 1].min(), ideal[..., 0].max() - s.width,
                                 ideal[..., 1].max() - s.height))) + 2
        return margin, ((ideal[..., 0] + margin).astype(np.float32), (ideal[..., 1] + margin).astype(np.float32))

    # ------------------------------------------------------------------ motion
    def joint_value(self, t_frames: float) -> float:
        """φ (rad, door) or l (m, drawer) at time ``t_frames`` (frames; fractions between frames)."""
        s = self.scene
        x = t_frames / max(s.n_frames - 1, 1)
        a = 0.5 * (1.0 - s.move_fraction)
        f = float(np.clip((x - a) / s.move_fraction, 0.0, 1.0))
        value = s.start + (s.end - s.start) * 0.5 * (1.0 - np.cos(np.pi * f))
        return np.radians(value) if s.kind == "door" else value

    def T_world_moving(self, t_frames: float) -> np.ndarray:
        """Pose (4, 4) of the moving part relative to its closed pose, in the world frame."""
        q = self.joint_value(t_frames)
        if self.scene.kind == "door":
            return pose_matrix(rotation_about_axis(self.axis_world, -q), np.zeros(3))
        return pose_matrix(np.eye(3), q * self.axis_world)

    def T_world_camera(self, t_frames: float) -> np.ndarray:
        s = self.scene
        phase, rate = self._shake
        w = 2 * np.pi * t_frames / s.fps
        wander = s.camera_shake_m * np.sin(rate * w + phase)  # (2, 3): position, then target
        return _look_at(np.asarray(s.camera_position_m) + wander[0],
                        np.asarray(s.camera_target_m) + 0.5 * wander[1])

    def _marker_centre_closed(self) -> np.ndarray:
        s = self.scene
        if s.kind == "door":
            return np.array([s.marker_offset_m, -0.001, s.marker_height_m])
        return np.array([s.marker_offset_m, -0.001, s.marker_height_m])

    def T_world_marker(self, t_frames: float) -> np.ndarray:
        """The moving marker's pose (OpenCV's marker frame: x right, y up, z towards −y) in the world."""
        R = np.column_stack([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
        return self.T_world_moving(t_frames) @ pose_matrix(R, self._marker_centre_closed())

    def T_world_reference(self) -> np.ndarray:
        x, z = self.scene.reference_position_m
        R = np.column_stack([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
        return pose_matrix(R, [x, WALL_Y_M - 0.001, z])

    # --------------------------------------------------------------- drawing
    def _planes(self, t_frames: float) -> list:
        s = self.scene
        L = s.marker_length_m
        x_hat, z_hat = np.array([1.0, 0, 0]), np.array([0, 0, 1.0])
        planes = _tiles([-2.4, WALL_Y_M, 2.6], x_hat, -z_hat, (5.4, 3.2), self._wall, 3)
        if self._reference is not None:
            x, z = s.reference_position_m
            planes.append(_plane([x - L, WALL_Y_M - 0.0005, z + L], x_hat, -z_hat, (2 * L, 2 * L),
                                 np.full((8, 8, 3), 245, np.uint8)))
            planes.append(_plane([x - L / 2, WALL_Y_M - 0.001, z + L / 2], x_hat, -z_hat, (L, L), self._reference))
        T = self.T_world_moving(t_frames)
        R, p = T[:3, :3], T[:3, 3]
        c = self._marker_centre_closed()
        if s.kind == "door":
            panel = _plane([0.0, 0.0, 2.0], x_hat, -z_hat, (0.8, 2.0), self._panel)
        else:
            panel = _plane([c[0] - 0.3, 0.0, c[2] + 0.15], x_hat, -z_hat, (0.6, 0.3), self._panel)
        marker = _plane(c + np.array([-L / 2, 0.0, L / 2]), x_hat, -z_hat, (L, L), self._marker)
        for origin, u, v, size, texture in (panel, marker):
            planes.append((R @ origin + p, R @ u, R @ v, size, texture))
        return planes

    def _ideal_image(self, t_frames: float) -> np.ndarray:
        s = self.scene
        ss, m = s.supersample, self._margin
        K = self.K.copy()
        K[:2, 2] += m
        K[:2] *= ss
        K[:2, 2] += 0.5 * (ss - 1)
        size = ((s.width + 2 * m) * ss, (s.height + 2 * m) * ss)
        image = np.full((size[1], size[0], 3), 40, np.uint8)
        T_camera_world = invert_pose(self.T_world_camera(t_frames))
        for origin, u, v, (w_m, h_m), texture in self._planes(t_frames):
            rows, cols = texture.shape[:2]
            R, t = T_camera_world[:3, :3], T_camera_world[:3, 3]
            corners = np.array([origin, origin + w_m * u, origin + w_m * u + h_m * v, origin + h_m * v])
            if np.any((corners @ R.T + t)[:, 2] < 0.05):
                continue
            # texture pixel (j, i) ↦ plane point origin + (j + ½) w/cols u + (i + ½) h/rows v ↦ ideal pixel
            A = np.column_stack([R @ u * (w_m / cols), R @ v * (h_m / rows),
                                 R @ (origin + 0.5 * (w_m / cols) * u + 0.5 * (h_m / rows) * v) + t])
            H = K @ A
            warped = cv2.warpPerspective(texture, H, size, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)
            mask = cv2.warpPerspective(np.full((rows, cols), 255, np.uint8), H, size, flags=cv2.INTER_NEAREST)
            cv2.copyTo(warped, mask, image)
        return cv2.resize(image, (s.width + 2 * m, s.height + 2 * m), interpolation=cv2.INTER_AREA)

    def frame(self, k: int) -> np.ndarray:
        """Frame ``k`` as recorded: BGR uint8 (height, width, 3)."""
        s = self.scene
        n = max(1, s.blur_samples)
        offsets = (np.arange(n) + 0.5) / n - 0.5 if n > 1 else np.zeros(1)
        ideal = np.mean([self._ideal_image(k + s.exposure_frames * o).astype(np.float32) for o in offsets], axis=0)
        image = cv2.remap(ideal, *self._maps, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        if s.blur_px > 0:
            image = cv2.GaussianBlur(image, (0, 0), s.blur_px)
        image = image + self._noise_rng.normal(0.0, s.noise_grey, image.shape)
        return np.clip(np.rint(image), 0, 255).astype(np.uint8)

    def frames(self):
        """Every frame in order (a generator)."""
        for k in range(self.scene.n_frames):
            yield self.frame(k)

    # ------------------------------------------------------------------ truth
    def truth(self) -> dict:
        """The joint in the reporting frame: ``model``, ``axis`` (3,), ``point`` (3,) on the hinge (door),
        ``angle_range_deg`` or ``travel_m``, and the frame's name."""
        s = self.scene
        if s.reference_id is None:
            T_frame_world = invert_pose(self.T_world_camera(0.0))
            frame = "camera"
        else:
            T_frame_world = invert_pose(self.T_world_reference())
            frame = f"marker_{s.reference_id}"
        out = {"model": "revolute" if s.kind == "door" else "prismatic", "frame": frame,
               "axis": T_frame_world[:3, :3] @ self.axis_world,
               "marker_poses": np.array([T_frame_world @ self.T_world_marker(k) for k in range(s.n_frames)])}
        if s.kind == "door":
            out["point"] = T_frame_world[:3, 3].copy()  # the hinge passes through the world origin
            out["angle_range_deg"] = abs(s.end - s.start)
        else:
            out["travel_m"] = abs(s.end - s.start)
        return out
