"""Point observations in the robot frame and the sensor's field of view (SPEC 5.2, 5.3).

Robot frame: origin at the robot's (x, y) on the floor (z = 0), x forward along
the heading θ, y to the left, z up. A landmark m (world frame, m) is observed as

    z = R(θ)ᵀ (m − [x, y, 0]ᵀ) + N(0, σ² I₃),

R(θ) the rotation by θ about the world z axis (SPEC 5.2). σ is a standard
deviation in metres (0.04 by default).

Fields of view (config ``sensor.fov``):

* ``cone`` (the paper's text): visible when the horizontal bearing
  atan2(z_y, z_x) is within ±``half_angle_deg`` (45°) and the 3D range |z| is at
  most ``max_range_m`` (4 m).
* ``pinhole`` (the authors' code): a camera at height ``camera_height_m`` above
  the robot origin looking along the robot's x axis. Camera axes: x_c = −y
  (image right), y_c = −(z − h) (image down), z_c = x (optical axis, depth).
  A point is visible when min_depth ≤ z_c ≤ max_depth and its projection
  u = f x_c/z_c + W/2, v = f y_c/z_c + H/2 lies in [0, W] × [0, H] pixels
  (f = 300 px, 320 × 240: ±28.1° horizontally, ±21.8° vertically).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stslam.geometry import rotate_about_z, rotation_z, rotation_z_derivative


def _pose(pose_xytheta) -> np.ndarray:
    pose = np.asarray(pose_xytheta, dtype=float)
    if pose.shape != (3,):
        raise ValueError(f"pose_xytheta must have shape (3,), got {pose.shape}")
    return pose


def observe(pose_xytheta, points_world) -> np.ndarray:
    """Noise-free observation z = R(θ)ᵀ(m − [x, y, 0]ᵀ) (SPEC 5.2).

    Parameters
    ----------
    pose_xytheta : array_like, shape (3,)
        Robot pose (x m, y m, θ rad), world frame.
    points_world : array_like, shape (3,) or (n, 3)
        Landmark positions m (m), world frame.

    Returns
    -------
    numpy.ndarray, shape (3,) or (n, 3)
        Points in the robot frame (m).
    """
    x, y, theta = _pose(pose_xytheta)
    m = np.asarray(points_world, dtype=float)
    if m.shape[-1] != 3 or m.ndim > 2:
        raise ValueError(f"points_world must have shape (3,) or (n, 3), got {m.shape}")
    offset = m - np.array([x, y, 0.0])
    return offset @ rotation_z(theta)  # row-wise Rᵀ·offset


class PoseObservation:
    """The observation model at one robot pose, for many landmarks (SPEC 5.2, 5.3).

    R(θ), dR(θ)/dθ and the pose's translation are evaluated once; :meth:`observe`
    gives each landmark's z and ∂z/∂pose with the expressions of :func:`observe`
    (so the same numbers), and ``H_m`` = ∂z/∂m = R(θ)ᵀ is the same for all.
    """

    def __init__(self, pose_xytheta):
        x, y, theta = _pose(pose_xytheta)
        self.t = np.array([x, y, 0.0])
        self.R = rotation_z(theta)
        self.H_m = self.R.T
        self.dRt = rotation_z_derivative(theta).T
        self.H_xy = -self.H_m[:, :2]  # ∂z/∂(x, y)

    def observe(self, point_world) -> tuple[np.ndarray, np.ndarray]:
        """z = R(θ)ᵀ(m − [x, y, 0]ᵀ) (3,) and ∂z/∂pose (3, 3) of one landmark m (3,)."""
        offset = np.asarray(point_world, dtype=float).reshape(3) - self.t
        H_pose = np.empty((3, 3))
        H_pose[:, :2] = self.H_xy
        H_pose[:, 2] = self.dRt @ offset  # ∂z/∂θ
        return offset @ self.R, H_pose

    def observe_many(self, points_world, out=None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`observe` of k landmarks m (k, 3) at once: z (k, 3) and ∂z/∂pose (k, 3, 3), the same numbers
        (each product a stacked (1, 3) × (3, 3) one, which rounds as the single one does). ``out`` (k, 3, ≥ 3):
        ∂z/∂pose is written into its first three columns, and ``out`` is returned in its place."""
        offsets = np.asarray(points_world, dtype=float).reshape(-1, 1, 3) - self.t
        H_pose = np.empty((offsets.shape[0], 3, 3)) if out is None else out
        H_pose[:, :, :2] = self.H_xy
        H_pose[:, :, 2] = (self.dRt @ offsets.transpose(0, 2, 1))[:, :, 0]  # ∂z/∂θ
        return (offsets @ self.R)[:, 0], H_pose


def observation_jacobians(pose_xytheta, point_world) -> tuple[np.ndarray, np.ndarray]:
    """∂z/∂pose (3, 3) and ∂z/∂m (3, 3) of :func:`observe` at one landmark (SPEC 5.3).

    ∂z/∂(x, y) = −R(θ)ᵀ[:, :2];  ∂z/∂θ = (dR(θ)ᵀ/dθ)(m − [x, y, 0]ᵀ);  ∂z/∂m = R(θ)ᵀ.
    """
    model = PoseObservation(pose_xytheta)
    return model.observe(point_world)[1], model.H_m


def point_from_observation(pose_xytheta, z_robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse sensor model m = R(θ) z + [x, y, 0]ᵀ and its Jacobians.

    Returns
    -------
    m : numpy.ndarray, shape (3,)
        Landmark position, world frame (m).
    dm_dpose : numpy.ndarray, shape (3, 3)
        ∂m/∂(x, y, θ): columns e_x, e_y and (dR/dθ) z.
    dm_dz : numpy.ndarray, shape (3, 3)
        ∂m/∂z = R(θ).
    """
    x, y, theta = _pose(pose_xytheta)
    z = np.asarray(z_robot, dtype=float).reshape(3)
    R = rotation_z(theta)
    dm_dpose = np.zeros((3, 3))
    dm_dpose[0, 0] = 1.0
    dm_dpose[1, 1] = 1.0
    dm_dpose[:, 2] = rotation_z_derivative(theta) @ z
    return R @ z + np.array([x, y, 0.0]), dm_dpose, R


def world_from_robot(poses_xytheta, z_robot) -> np.ndarray:
    """Inverse sensor model m = R(θ) z + [x, y, 0]ᵀ (SPEC 5.2) for many observations at once.

    Parameters
    ----------
    poses_xytheta : array_like, shape (3,) or (n, 3)
        One robot pose for all observations, or the pose of each (x m, y m, θ rad).
    z_robot : array_like, shape (n, 3)
        Observations in the robot frame (m).

    Returns
    -------
    numpy.ndarray, shape (n, 3)
        Points in the world frame (m).
    """
    poses = np.asarray(poses_xytheta, dtype=float)
    z = np.asarray(z_robot, dtype=float).reshape(-1, 3)
    if poses.shape not in ((3,), (z.shape[0], 3)):
        raise ValueError(f"poses_xytheta must have shape (3,) or ({z.shape[0]}, 3), got {poses.shape}")
    if poses.ndim == 1:  # one pose: R(θ) zᵢ as stacked products, the numbers of point_from_observation's R @ z
        return (rotation_z(poses[2]) @ z[:, :, None])[:, :, 0] + np.array([poses[0], poses[1], 0.0])
    m = rotate_about_z(z, poses[:, 2])  # one pose each: R(θᵢ) zᵢ coordinate by coordinate
    m[:, :2] += poses[:, :2]
    return m


def observation_noise(rng: np.random.Generator, sigma_m: float, shape) -> np.ndarray:
    """Observation noise ν = σ ε, ε ~ N(0, I) standard normals of ``shape`` (…, 3), σ in m (SPEC 5.2)."""
    return sigma_m * rng.standard_normal(shape)


def pose_induced_variance(pose_xytheta, pose_cov, zs_robot) -> np.ndarray:
    """Largest variance (m²) the pose uncertainty gives each observed point's world position.

    λ_max(J P_pose Jᵀ) with J = ∂m/∂(x, y, θ) = [e_x, e_y, (dR/dθ) z] of the
    inverse sensor model m = R(θ) z + [x, y, 0]ᵀ (SPEC 5.2), for k points at once.

    Parameters
    ----------
    pose_xytheta : array_like, shape (3,)
    pose_cov : array_like, shape (3, 3)
    zs_robot : array_like, shape (k, 3)
        Observations in the robot frame (m).

    Returns
    -------
    numpy.ndarray, shape (k,)
    """
    zs = np.asarray(zs_robot, dtype=float).reshape(-1, 3)
    J = np.zeros((zs.shape[0], 3, 3))
    J[:, 0, 0] = 1.0
    J[:, 1, 1] = 1.0
    J[:, :, 2] = zs @ rotation_z_derivative(_pose(pose_xytheta)[2]).T
    return np.linalg.eigvalsh(J @ np.asarray(pose_cov, dtype=float) @ J.transpose(0, 2, 1))[:, -1]


def world_point_covariances(pose_xytheta, pose_cov, zs_robot, Rs_robot) -> np.ndarray:
    """Covariance (m²) of each observed point's world position: R(θ) R_i R(θ)ᵀ + J_i P_pose J_iᵀ.

    The sensor noise rotated into the world plus the share of the pose
    uncertainty, J_i = ∂m/∂(x, y, θ) of m = R(θ) z_i + [x, y, 0]ᵀ (SPEC 5.2, 13);
    the landmark's correlation with the pose is left out. ``zs_robot`` (k, 3),
    ``Rs_robot`` (k, 3, 3) in the robot frame; returns (k, 3, 3).
    """
    zs = np.asarray(zs_robot, dtype=float).reshape(-1, 3)
    theta = _pose(pose_xytheta)[2]
    J = np.zeros((zs.shape[0], 3, 3))
    J[:, 0, 0] = 1.0
    J[:, 1, 1] = 1.0
    J[:, :, 2] = zs @ rotation_z_derivative(theta).T
    rot = rotation_z(theta)
    return rot @ np.asarray(Rs_robot, dtype=float) @ rot.T + J @ np.asarray(pose_cov, dtype=float) @ J.transpose(0, 2, 1)


@dataclass(frozen=True)
class ConeFov:
    """The paper's field of view: ±``half_angle_rad`` about the heading, 3D range ≤ ``max_range_m``."""

    half_angle_rad: float = np.pi / 4
    max_range_m: float = 4.0

    def contains(self, points_robot) -> np.ndarray:
        """Visibility mask, shape (n,), of points (n, 3) in the robot frame."""
        z = np.atleast_2d(np.asarray(points_robot, dtype=float))
        bearing = np.arctan2(z[:, 1], z[:, 0])
        return (np.abs(bearing) <= self.half_angle_rad) & (np.linalg.norm(z, axis=1) <= self.max_range_m)


@dataclass(frozen=True)
class PinholeFov:
    """The authors' camera: pinhole, focal ``focal_px``, image ``width_px`` × ``height_px``, depth limits."""

    focal_px: float = 300.0
    width_px: float = 320.0
    height_px: float = 240.0
    min_depth_m: float = 0.5
    max_depth_m: float = 4.0
    camera_height_m: float = 0.0

    def pixels(self, points_robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Pixel coordinates u, v (px) and depth z_c (m) of points (n, 3) in the robot frame."""
        z = np.atleast_2d(np.asarray(points_robot, dtype=float))
        depth = z[:, 0]
        x_c = -z[:, 1]
        y_c = -(z[:, 2] - self.camera_height_m)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = self.focal_px * x_c / depth + 0.5 * self.width_px
            v = self.focal_px * y_c / depth + 0.5 * self.height_px
        return u, v, depth

    def contains(self, points_robot) -> np.ndarray:
        """Visibility mask, shape (n,), of points (n, 3) in the robot frame."""
        u, v, depth = self.pixels(points_robot)
        in_depth = (depth >= self.min_depth_m) & (depth <= self.max_depth_m)
        with np.errstate(invalid="ignore"):
            in_image = (u >= 0) & (u <= self.width_px) & (v >= 0) & (v <= self.height_px)
        return in_depth & in_image


@dataclass(frozen=True)
class Sensor:
    """Observation noise σ (m, standard deviation per axis) and field of view."""

    sigma_m: float
    fov: ConeFov | PinholeFov

    @property
    def R(self) -> np.ndarray:
        """Observation noise covariance σ² I₃ (robot frame), shape (3, 3)."""
        return self.sigma_m**2 * np.eye(3)

