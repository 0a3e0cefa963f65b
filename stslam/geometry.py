"""Rigid-body geometry every layer shares: rotations, rigid transforms, planar poses, axes, depth noise.

The lowest layer of stslam (NumPy only, no other stslam import). Conventions,
written once:

* ``rotation_z(θ)`` is R(θ), the rotation by θ (rad) about +z, counter-clockwise
  seen from above: R(θ)·[1, 0, 0]ᵀ = [cos θ, sin θ, 0]ᵀ. For a planar robot at
  (x, y, θ) it maps robot-frame vectors into the world frame (SPEC 5.2).
* A rotation by φ about a unit axis a turns right-handedly about a (Rodrigues).
* Poses are 4 × 4 homogeneous matrices named ``T_<to>_<from>``:
  X_to = T_to_from X_from, with rotation T[:3, :3] and translation T[:3, 3]
  (the origin of frame <from> expressed in frame <to>).
* A planar pose (x m, y m, θ rad) is T_world_base with yaw θ about z and its
  origin on the floor (z = 0).
"""

from __future__ import annotations

import math

import numpy as np

E_Z = (0.0, 0.0, 1.0)


# ------------------------------------------------------------------ rotations

def rotation_z(theta_rad: float) -> np.ndarray:
    """R(θ), shape (3, 3): rotation by θ (rad) about z (world ← robot, SPEC 5.2)."""
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rotation_z_derivative(theta_rad: float) -> np.ndarray:
    """dR(θ)/dθ, shape (3, 3), of :func:`rotation_z` (SPEC 5.3)."""
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    return np.array([[-s, -c, 0.0], [c, -s, 0.0], [0.0, 0.0, 0.0]])


def rotate_about_z(vectors, theta_rad) -> np.ndarray:
    """R(θ) v for vectors (n, 3), coordinate by coordinate, one angle for all or one each (n,).

    (x, y, z) ↦ (cos θ·x − sin θ·y, sin θ·x + cos θ·y, z): the same R(θ) as
    :func:`rotation_z`, vectorised over the angles.
    """
    v = np.asarray(vectors, dtype=float)
    if v.ndim != 2 or v.shape[1] != 3:
        raise ValueError(f"vectors must have shape (n, 3), got {v.shape}")
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    return np.column_stack([c * v[:, 0] - s * v[:, 1], s * v[:, 0] + c * v[:, 1], v[:, 2]])


def skew(vector) -> np.ndarray:
    """[a]×, shape (3, 3): the matrix with [a]× b = a × b."""
    a = np.asarray(vector, dtype=float).reshape(3)
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def rotation_about_axis(axis_unit, angle_rad: float) -> np.ndarray:
    """Rotation matrix (3, 3) turning by ``angle_rad`` about the unit axis ``axis_unit`` (3,).

    Rodrigues' formula R = I + sin φ [a]× + (1 − cos φ) [a]×² (e.g. Murray, Li
    and Sastry 1994, Eq. 2.14).
    """
    K = skew(axis_unit)
    return np.eye(3) + np.sin(angle_rad) * K + (1.0 - np.cos(angle_rad)) * (K @ K)


def rotate_about_axis(vector, axis_unit, angles_rad) -> np.ndarray:
    """One vector v (3,) turned by each angle φ (n,) about the unit axis a (3,): shape (n, 3).

    Rodrigues' formula in vector form, v cos φ + (a × v) sin φ + a (a·v)(1 − cos φ):
    the same rotation as :func:`rotation_about_axis`, without a matrix per angle.
    """
    v = np.asarray(vector, dtype=float).reshape(3)
    a = np.asarray(axis_unit, dtype=float).reshape(3)
    angles = np.asarray(angles_rad, dtype=float).reshape(-1)
    c, s = np.cos(angles)[:, None], np.sin(angles)[:, None]
    return v * c + np.cross(a, v) * s + np.outer(1 - c[:, 0], a) * np.dot(a, v)


# ----------------------------------------------------------- rigid transforms

def pose_matrix(R, t) -> np.ndarray:
    """Homogeneous 4 × 4 transform from rotation ``R`` (3, 3) and translation ``t`` (3,) m."""
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


def invert_pose(T) -> np.ndarray:
    """Inverse of rigid transforms (4, 4) or stacked (..., 4, 4): (R, t)⁻¹ = (Rᵀ, −Rᵀ t)."""
    T = np.asarray(T, dtype=float)
    if T.shape[-2:] != (4, 4):
        raise ValueError(f"T must have shape (..., 4, 4), got {T.shape}")
    out = np.zeros_like(T)
    Rt = np.swapaxes(T[..., :3, :3], -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, T[..., :3, 3])
    out[..., 3, 3] = 1.0
    return out


def transform_points(T_to_from, points_from) -> np.ndarray:
    """Points (n, 3) in frame ``from`` mapped to frame ``to``: X_to = R X_from + t."""
    T = np.asarray(T_to_from, dtype=float)
    P = np.asarray(points_from, dtype=float).reshape(-1, 3)
    return P @ T[:3, :3].T + T[:3, 3]


def planar_pose_matrix(pose_xytheta) -> np.ndarray:
    """T_world_base (4, 4) of a planar pose (x m, y m, θ rad): yaw θ about z, on the floor.

    The yaw block is :func:`rotation_about_axis` about e_z; its diagonal,
    1 − (1 − cos θ), can differ from :func:`rotation_z`'s cos θ by one rounding.
    """
    x, y, theta = (float(v) for v in pose_xytheta)
    return pose_matrix(rotation_about_axis(E_Z, theta), [x, y, 0.0])


def planar_pose_from_matrix(T_world_base) -> np.ndarray:
    """(x m, y m, θ rad) of a 4 × 4 pose: its translation's x, y and its yaw atan2(R[1, 0], R[0, 0])."""
    T = np.asarray(T_world_base, dtype=float)
    return np.array([T[0, 3], T[1, 3], np.arctan2(T[1, 0], T[0, 0])])


# ----------------------------------------------------------------------- axes

def cross3(a, b) -> np.ndarray:
    """a × b (3,) of two 3-vectors, as ``np.cross`` computes it (the same products and differences, so the
    same numbers), without its axis handling, which costs some thirty times the arithmetic."""
    (a0, a1, a2), (b0, b1, b2) = np.asarray(a, dtype=float).tolist(), np.asarray(b, dtype=float).tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def _check_vector3(v, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected a finite vector of shape (3,), got {a!r}")
    return a


def _vector3(v, name: str) -> tuple[float, float, float]:
    """The three coordinates of a finite vector (3,), as floats (checked on them: numpy's isfinite and all
    cost more than the three tests)."""
    a = np.asarray(v, dtype=float)
    x = a.tolist()
    if a.shape != (3,) or not (math.isfinite(x[0]) and math.isfinite(x[1]) and math.isfinite(x[2])):
        raise ValueError(f"{name}: expected a finite vector of shape (3,), got {a!r}")
    return x[0], x[1], x[2]


def axis_angle_deg(a_hat, a) -> float:
    """Angle between two axis directions, sign-blind: arccos(|â·a| / (|â||a|)) in degrees (SPEC 7).

    Computed as atan2(‖â × a‖, |â·a|), which equals the arccos form but keeps
    full precision for nearly parallel axes. In floats, coordinate by coordinate: the
    products and sums of ``np.cross`` and ``np.dot`` in their order, so the same numbers.
    """
    (u0, u1, u2), (v0, v1, v2) = _vector3(a_hat, "a_hat"), _vector3(a, "a")
    if u0 * u0 + u1 * u1 + u2 * u2 == 0.0 or v0 * v0 + v1 * v1 + v2 * v2 == 0.0:
        raise ValueError("axis directions must be non-zero")
    c0, c1, c2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0  # â × a
    return math.degrees(float(np.arctan2(math.sqrt(c0 * c0 + c1 * c1 + c2 * c2), abs(u0 * v0 + u1 * v1 + u2 * v2))))


def axis_line_distance(p1, d1, p2, d2) -> float:
    """Shortest distance between the lines p1 + s·d1 and p2 + s·d2, m (SPEC 7).

    Skew lines: |(p2 − p1)·(d1 × d2)| / ‖d1 × d2‖. Parallel lines (sine of the
    angle below 1e-12): ‖(p2 − p1) × d1‖ / ‖d1‖, the distance of p2 from line 1.
    In floats, as :func:`axis_angle_deg`.
    """
    (p0, p1_, p2_), (a0, a1, a2) = _vector3(p1, "p1"), _vector3(d1, "d1")
    (q0, q1, q2), (b0, b1, b2) = _vector3(p2, "p2"), _vector3(d2, "d2")
    n1, n2 = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2), math.sqrt(b0 * b0 + b1 * b1 + b2 * b2)
    if n1 == 0.0 or n2 == 0.0:
        raise ValueError("line directions must be non-zero")
    w0, w1, w2 = q0 - p0, q1 - p1_, q2 - p2_
    c0, c1, c2 = a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0  # d1 × d2
    nc = math.sqrt(c0 * c0 + c1 * c1 + c2 * c2)
    if nc <= 1e-12 * n1 * n2:
        e0, e1, e2 = w1 * a2 - w2 * a1, w2 * a0 - w0 * a2, w0 * a1 - w1 * a0  # w × d1
        return math.sqrt(e0 * e0 + e1 * e1 + e2 * e2) / n1
    return abs(w0 * c0 + w1 * c1 + w2 * c2) / nc


def _check_vectors3(v, name: str) -> np.ndarray:
    a = np.asarray(v, dtype=float)
    if a.ndim != 2 or a.shape[1] != 3 or not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite vectors of shape (n, 3), got shape {a.shape}")
    return a


def _row_dots(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """u·v over the last axis, summed left to right as ``np.dot`` of two 3-vectors (the same floats)."""
    return (u * v).sum(axis=-1)


def pairwise_axis_angles_deg(a_hat, a) -> np.ndarray:
    """(n, m) matrix of :func:`axis_angle_deg` between every row of ``a_hat`` (n, 3) and of ``a`` (m, 3) (SPEC 7).

    The same operations, element by element, as the one-pair function, so the same floats.
    """
    u, v = _check_vectors3(a_hat, "a_hat")[:, None, :], _check_vectors3(a, "a")[None, :, :]
    if not (_row_dots(u, u).all() and _row_dots(v, v).all()):
        raise ValueError("axis directions must be non-zero")
    c = np.cross(u, v)
    return np.degrees(np.arctan2(np.sqrt(_row_dots(c, c)), np.abs(_row_dots(u, v))))


def pairwise_axis_line_distances(p1, d1, p2, d2) -> np.ndarray:
    """(n, m) matrix of :func:`axis_line_distance` between lines (p1, d1) (n, 3) and (p2, d2) (m, 3), m (SPEC 7).

    The same operations, element by element, as the one-pair function, so the same floats.
    """
    p1, d1 = _check_vectors3(p1, "p1")[:, None, :], _check_vectors3(d1, "d1")[:, None, :]
    p2, d2 = _check_vectors3(p2, "p2")[None, :, :], _check_vectors3(d2, "d2")[None, :, :]
    n1, n2 = np.sqrt(_row_dots(d1, d1)), np.sqrt(_row_dots(d2, d2))
    if not (n1.all() and n2.all()):
        raise ValueError("line directions must be non-zero")
    w = p2 - p1
    c = np.cross(d1, d2)
    nc = np.sqrt(_row_dots(c, c))
    parallel = nc <= 1e-12 * n1 * n2
    wd = np.cross(w, d1)
    with np.errstate(divide="ignore", invalid="ignore"):
        skew = np.abs(_row_dots(w, c)) / nc
    return np.where(parallel, np.sqrt(_row_dots(wd, wd)) / n1, skew)

# ------------------------------------------------------------------ depth noise

def depth_noise_std(depth_m, coefficient: float):
    """Structured-light depth noise σ_z = c·z² (m) at depth z (m), c in m⁻¹ (SPEC 9: c ≈ 1.5·10⁻³)."""
    return coefficient * np.asarray(depth_m) ** 2
