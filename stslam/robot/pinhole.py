"""Pinhole camera conventions shared by the renderer, the MCAP reader and the fridge front end (SPEC 9).

Camera optical frame (ROS/Foxglove convention): origin at the optical centre,
+x right in the image, +y down, +z forward along the optical axis. Pixel
(u, v) has column u and row v; the centre of the top-left pixel is (0, 0).

Intrinsics K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (pixels): a point X_c in
the camera frame projects to (u, v, 1)ᵀ ∝ K X_c. Depth z is the +z coordinate
of X_c (not the range along the ray), metres.

Poses are 4 × 4 homogeneous matrices named ``T_<to>_<from>`` (:mod:`stslam.geometry`):
``X_world = T_world_camera @ X_camera`` (so ``T_world_camera``'s translation is
the camera centre in the world frame).
"""

from __future__ import annotations

import numpy as np


def intrinsics_matrix(fx: float, fy: float, cx: float, cy: float) -> np.ndarray:
    """K (3, 3) from focal lengths and principal point, all in pixels."""
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])


def project_points(K, points_camera) -> tuple[np.ndarray, np.ndarray]:
    """Pixel coordinates (n, 2) and depths z (n,) m of camera-frame points (n, 3).

    (u, v) = (fx x/z + cx, fy y/z + cy); points with z ≤ 0 give non-finite or
    meaningless pixels: check the returned depth.
    """
    P = np.asarray(points_camera, dtype=float).reshape(-1, 3)
    K = np.asarray(K, dtype=float)
    z = P[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = (P @ K.T)[:, :2] / z[:, None]
    return uv, z


def back_project_pixels(K, pixels_uv, depth_m) -> np.ndarray:
    """Camera-frame points (n, 3) of pixels (n, 2) at depth z (n,) m: X_c = z K⁻¹ (u, v, 1)ᵀ."""
    uv = np.asarray(pixels_uv, dtype=float).reshape(-1, 2)
    z = np.asarray(depth_m, dtype=float).reshape(-1)
    K = np.asarray(K, dtype=float)
    x = (uv[:, 0] - K[0, 2]) / K[0, 0]
    y = (uv[:, 1] - K[1, 2]) / K[1, 1]
    return np.column_stack([x * z, y * z, z])


def rotation_body_from_optical() -> np.ndarray:
    """R_body_optical (3, 3): axes of the optical frame (x right, y down, z forward)
    expressed in a body frame whose x points forward, y left and z up (ROS REP 103)."""
    return np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
