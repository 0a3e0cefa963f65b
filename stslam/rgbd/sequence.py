"""The fridge-door RGB-D sequence: robot path, door motion, odometry and rendered frames (SPEC 9).

A planar robot (SPEC 5.1) drives a smooth arc around the fridge with a camera
mounted on it looking to its left, so the fridge stays in view. The door
stays closed, swings open to ``door_open_deg``, pauses, closes and pauses
again. Frames are rendered with :mod:`stslam.rgbd.renderer` and get the depth
sensor's noise and holes.

Randomness: textures, odometry noise and per-frame sensor noise come from
independent streams ``SeedSequence(seed, spawn_key=(stream, …))`` so that a
frame can be rendered on its own and the same seed always gives the same data.

Frames (SPEC 9): ``world`` (z up, floor z = 0), ``base_link`` (robot: x forward,
y left, z up, on the floor), ``camera_optical`` (x right, y down, z forward; see
:mod:`stslam.robot.pinhole`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stslam.geometry import E_Z, planar_pose_matrix, pose_matrix, rotation_about_axis
from stslam.robot.pinhole import intrinsics_matrix, rotation_body_from_optical
from stslam.rgbd.renderer import PinholeImage, RenderedView, render_view, sensor_depth, sensor_rgb, texture_pyramid
from stslam.robot.motion import check_alpha, control_between, move, sample_noisy_controls
from stslam.rgbd.scene import FridgeRoom, fridge_room

STREAM_TEXTURES, STREAM_ODOMETRY, STREAM_SENSOR = 0, 1, 2


@dataclass(frozen=True)
class SequenceConfig:
    """Parameters of the fridge sequence (units in the names; angles in degrees).

    The door profile ``door_times`` holds the fractions of the sequence at
    which the door starts opening, is fully open, starts closing and is
    closed again. The path circles the fridge front centre from polar angle
    ``path_start_deg`` to ``path_end_deg`` (0 = straight in front, positive
    towards the hinge side) at radius ``path_radius_m`` ± ``path_radius_swing_m``.
    """

    n_frames: int = 300
    width: int = 640
    height: int = 480
    rate_hz: float = 30.0
    hfov_deg: float = 62.7
    camera_height_m: float = 1.0
    camera_yaw_deg: float = 90.0
    path_radius_m: float = 2.5
    path_radius_swing_m: float = 0.2
    path_start_deg: float = 5.0
    path_end_deg: float = 70.0
    door_open_deg: float = 90.0
    door_times: tuple = (0.15, 0.4, 0.6, 0.85)
    alpha: tuple = (0.1, 0.05, 0.05, 0.1)
    depth_noise_coefficient: float = 1.5e-3
    depth_min_m: float = 0.3
    depth_max_m: float = 4.0
    max_incidence_deg: float = 75.0
    rgb_noise_std: float = 2.0


@dataclass
class SequenceFrame:
    """One time step of the sequence.

    Attributes
    ----------
    index : int
    t_s : float
        Time since the first frame (s).
    rgb : numpy.ndarray, shape (H, W, 3), uint8
    depth_m : numpy.ndarray, shape (H, W), float32
        Sensor depth (m), NaN where the sensor has no return.
    label : numpy.ndarray, shape (H, W), uint8
        Surface label per pixel (``stslam.rgbd.scene.LABEL_*``).
    T_world_base : numpy.ndarray, shape (4, 4)
        Ground-truth robot pose.
    T_world_base_odom : numpy.ndarray, shape (4, 4)
        Robot pose integrated from the noisy odometry controls.
    door_angle_rad : float
    """

    index: int
    t_s: float
    rgb: np.ndarray
    depth_m: np.ndarray
    label: np.ndarray
    T_world_base: np.ndarray
    T_world_base_odom: np.ndarray
    door_angle_rad: float


def intrinsics_for(width: int, height: int, hfov_deg: float) -> np.ndarray:
    """K (3, 3) of square pixels with horizontal field of view ``hfov_deg``, centred principal point."""
    f = 0.5 * width / np.tan(0.5 * np.deg2rad(hfov_deg))
    return intrinsics_matrix(f, f, 0.5 * (width - 1), 0.5 * (height - 1))


def base_camera_transform(camera_height_m: float, camera_yaw_deg: float) -> np.ndarray:
    """T_base_camera (4, 4): the optical frame on a mast at ``camera_height_m``, turned by
    ``camera_yaw_deg`` about base z (90° = looking to the robot's left)."""
    R_base_body = rotation_about_axis(E_Z, np.deg2rad(camera_yaw_deg))
    return pose_matrix(R_base_body @ rotation_body_from_optical(), [0.0, 0.0, camera_height_m])


def door_angle_profile(tau, open_rad: float, times) -> np.ndarray:
    """Door angle (rad) at sequence fractions ``tau`` (n,): closed, cosine-eased opening,
    open, cosine-eased closing, closed; ``times`` = (open start, open end, close start, close end)."""
    tau = np.asarray(tau, dtype=float)
    t0, t1, t2, t3 = times
    opening = 0.5 - 0.5 * np.cos(np.pi * np.clip((tau - t0) / (t1 - t0), 0.0, 1.0))
    closing = 0.5 + 0.5 * np.cos(np.pi * np.clip((tau - t2) / (t3 - t2), 0.0, 1.0))
    return open_rad * np.where(tau < t2, opening, closing)


def path_poses(tau, centre_xy, radius_m: float, swing_m: float, start_rad: float, end_rad: float) -> np.ndarray:
    """Planar poses (n, 3) on the arc around ``centre_xy`` at sequence fractions ``tau`` (n,).

    Polar angle φ(τ) = φ0 + (φ1 − φ0)(τ − 0.3 sin(2πτ)/2π) (speed varies ±30 %),
    radius ρ(τ) = ρ0 + Δρ cos(πτ); position c + ρ (sin φ, −cos φ); heading θ
    along the path's tangent (a unicycle drives forwards).
    """
    tau = np.asarray(tau, dtype=float)
    span = end_rad - start_rad
    phi = start_rad + span * (tau - 0.3 * np.sin(2 * np.pi * tau) / (2 * np.pi))
    dphi = span * (1.0 - 0.3 * np.cos(2 * np.pi * tau))
    rho = radius_m + swing_m * np.cos(np.pi * tau)
    drho = -np.pi * swing_m * np.sin(np.pi * tau)
    x = centre_xy[0] + rho * np.sin(phi)
    y = centre_xy[1] - rho * np.cos(phi)
    dx = drho * np.sin(phi) + rho * np.cos(phi) * dphi
    dy = -drho * np.cos(phi) + rho * np.sin(phi) * dphi
    return np.column_stack([x, y, np.arctan2(dy, dx)])


def integrate_controls(start_xytheta, controls_vw, dt: float) -> np.ndarray:
    """Poses (n + 1, 3) from ``start_xytheta`` driven by ``controls_vw`` (n, 2) (SPEC 5.1 motion model)."""
    poses = [np.asarray(start_xytheta, dtype=float)]
    for u in np.asarray(controls_vw, dtype=float):
        poses.append(move(poses[-1], u, dt))
    return np.array(poses)


def _rng(seed: int, *key: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence(entropy=seed, spawn_key=key))


class FridgeSequence:
    """The whole sequence for one seed: trajectories up front, frames rendered on demand.

    Attributes
    ----------
    config : SequenceConfig
    seed : int
    room : stslam.rgbd.scene.FridgeRoom
    K : numpy.ndarray, shape (3, 3)
    T_base_camera : numpy.ndarray, shape (4, 4)
    times_s : numpy.ndarray, shape (n,)
    poses_gt_xytheta, poses_odom_xytheta : numpy.ndarray, shape (n, 3)
        Ground-truth and odometry robot poses (m, m, rad), world frame.
    controls_gt_vw, controls_odom_vw : numpy.ndarray, shape (n − 1, 2)
        True and odometry controls (m/s, rad/s) between consecutive frames.
    door_angles_rad : numpy.ndarray, shape (n,)
    """

    def __init__(self, config: SequenceConfig, seed: int):
        self.config = config
        self.seed = int(seed)
        n = config.n_frames
        self.room: FridgeRoom = fridge_room(_rng(self.seed, STREAM_TEXTURES))
        self._pyramids = [texture_pyramid(t) for t in self.room.textures]
        self.K = intrinsics_for(config.width, config.height, config.hfov_deg)
        self._camera = PinholeImage.from_intrinsics(self.K, config.width, config.height)
        self.T_base_camera = base_camera_transform(config.camera_height_m, config.camera_yaw_deg)
        dt = 1.0 / config.rate_hz
        self.times_s = np.arange(n) * dt
        tau = np.linspace(0.0, 1.0, n)
        sampled = path_poses(tau, self.room.fridge_front_centre_world[:2], config.path_radius_m,
                             config.path_radius_swing_m, np.deg2rad(config.path_start_deg),
                             np.deg2rad(config.path_end_deg))
        # SPEC 5.1: true controls between the sampled poses, re-integrated so the ground truth
        # follows the motion model exactly; odometry integrates u + N(0, S(u)).
        self.controls_gt_vw = np.array([control_between(sampled[k], sampled[k + 1], dt) for k in range(n - 1)])
        self.controls_gt_vw = self.controls_gt_vw.reshape(-1, 2)
        self.poses_gt_xytheta = integrate_controls(sampled[0], self.controls_gt_vw, dt)
        self.controls_odom_vw = sample_noisy_controls(self.controls_gt_vw, check_alpha(config.alpha),
                                                      _rng(self.seed, STREAM_ODOMETRY))
        self.poses_odom_xytheta = integrate_controls(sampled[0], self.controls_odom_vw, dt)
        self.door_angles_rad = door_angle_profile(tau, np.deg2rad(config.door_open_deg), config.door_times)

    def __len__(self) -> int:
        return self.config.n_frames

    @property
    def hinge_point_world(self) -> np.ndarray:
        return self.room.hinge_point_world

    @property
    def hinge_axis_world(self) -> np.ndarray:
        return self.room.hinge_axis_world

    def T_world_camera(self, index: int) -> np.ndarray:
        """Ground-truth camera pose (4, 4) at frame ``index``."""
        return planar_pose_matrix(self.poses_gt_xytheta[index]) @ self.T_base_camera

    def render(self, index: int) -> RenderedView:
        """Noise-free view of frame ``index``: colour, true depth, surface labels, incidence."""
        return render_view(self.room.quads_at(float(self.door_angles_rad[index])), self._pyramids,
                           self._camera, self.T_world_camera(index))

    def frame(self, index: int) -> SequenceFrame:
        """Render frame ``index`` with its sensor noise (deterministic per seed and index)."""
        c = self.config
        view = self.render(index)
        rng = _rng(self.seed, STREAM_SENSOR, index)
        depth = sensor_depth(view.depth_m, view.cos_incidence, rng, noise_coefficient=c.depth_noise_coefficient,
                             min_range_m=c.depth_min_m, max_range_m=c.depth_max_m,
                             max_incidence_deg=c.max_incidence_deg)
        rgb = sensor_rgb(view.rgb, rng, c.rgb_noise_std)
        return SequenceFrame(
            index=index, t_s=float(self.times_s[index]), rgb=rgb, depth_m=depth, label=view.label,
            T_world_base=planar_pose_matrix(self.poses_gt_xytheta[index]),
            T_world_base_odom=planar_pose_matrix(self.poses_odom_xytheta[index]),
            door_angle_rad=float(self.door_angles_rad[index]),
        )

    def frames(self):
        """Iterate over all frames in order."""
        for index in range(len(self)):
            yield self.frame(index)


@dataclass(frozen=True)
class DataRequest:
    """The fridge data set to generate (:mod:`stslam.experiments.datasets`; read by :mod:`stslam.config.rgbd`).

    Attributes
    ----------
    seed : int
        The whole data set (textures, odometry noise, sensor noise) follows from it.
    out : pathlib.Path
        The data file to write.
    sequence : SequenceConfig
        What to render (:mod:`stslam.rgbd.sequence`).
    depth_encoding : str
        One of :data:`stslam.io.mcap_topics.DEPTH_WRITE_ENCODINGS`.
    overwrite : bool
        Replace an existing ``out``.
    show_progress : bool
        A progress bar on stderr.
    """

    seed: int
    out: Path
    sequence: SequenceConfig
    depth_encoding: str
    overwrite: bool = False
    show_progress: bool = False
