"""Trajectory and structure error metrics (SPEC 7).

Trajectories are TUM rows ``t x y z qx qy qz qw`` (shape (n, 8), metres,
unit quaternions in x, y, z, w order), estimate and ground truth already
associated row by row. The trajectory metrics agree with evo's
``evo.core.metrics.APE`` (translation part, after ``align``) and ``RPE``
(translation part, frame-index pairs, ``all_pairs=True``) to 1e-9
(``tests/eval/test_metrics.py``).
"""

from __future__ import annotations

import numpy as np

from stslam.errors import StslamError
from stslam.geometry import axis_angle_deg, axis_line_distance, invert_pose

__all__ = [
    "AlignmentError", "ate_rmse", "axis_angle_deg", "axis_line_distance", "centre_error", "check_tum",
    "radius_error", "relative_translation_errors", "rpe_rmse", "se3_from_tum", "umeyama_alignment",
]


class AlignmentError(StslamError):
    """The point sets do not fix a rigid alignment (rank-deficient cross-covariance)."""


def check_tum(rows, name: str = "trajectory") -> np.ndarray:
    """Float64 copy of TUM rows, shape (n, 8), finite; ValueError naming ``name`` otherwise."""
    a = np.asarray(rows, dtype=float)
    if a.ndim != 2 or a.shape[1] != 8 or a.shape[0] < 1:
        raise ValueError(f"{name}: expected TUM rows of shape (n, 8), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: contains non-finite values")
    return a


def _check_pair(tum_gt, tum_est) -> tuple[np.ndarray, np.ndarray]:
    gt, est = check_tum(tum_gt, "tum_gt"), check_tum(tum_est, "tum_est")
    if gt.shape != est.shape:
        raise ValueError(f"tum_gt and tum_est must have the same shape, got {gt.shape} and {est.shape}")
    return gt, est


def umeyama_alignment(points_src, points_dst) -> tuple[np.ndarray, np.ndarray]:
    """Rigid (no scale) least-squares alignment of ``points_src`` onto ``points_dst``.

    Finds R ∈ SO(d), t minimising Σ_i ‖y_i − (R x_i + t)‖² (Umeyama 1991,
    Eqs. 34–43 with scale 1; Horn 1987):

    * means μ_x, μ_y;  cross-covariance Σ_xy = (1/n) Σ_i (y_i − μ_y)(x_i − μ_x)ᵀ  (Eq. 38)
    * Σ_xy = U D Vᵀ;  S = diag(1, …, 1, det(U)·det(V))  (Eq. 43, no reflection)
    * R = U S Vᵀ  (Eq. 40);  t = μ_y − R μ_x  (Eq. 41)

    The rotation is unique only when rank(Σ_xy) ≥ d − 1, which is checked
    before it is used (a straight-line or single-point trajectory fails).

    Parameters
    ----------
    points_src : array_like, shape (n, d)
        Points to move (e.g. estimated positions, m).
    points_dst : array_like, shape (n, d)
        Target points (e.g. ground-truth positions, m).

    Returns
    -------
    R : numpy.ndarray, shape (d, d)
        Rotation, det R = +1.
    t : numpy.ndarray, shape (d,)
        Translation (m): aligned points are ``points_src @ R.T + t``.

    Raises
    ------
    AlignmentError
        rank(Σ_xy) < d − 1; the message lists the singular values.
    """
    x = np.asarray(points_src, dtype=float)
    y = np.asarray(points_dst, dtype=float)
    if x.ndim != 2 or x.shape != y.shape:
        raise ValueError(f"points_src and points_dst must both have shape (n, d), got {x.shape} and {y.shape}")
    d = x.shape[1]
    mu_x, mu_y = x.mean(axis=0), y.mean(axis=0)
    cov_xy = (y - mu_y).T @ (x - mu_x) / x.shape[0]  # Eq. 38
    U, D, Vt = np.linalg.svd(cov_xy)
    tol = max(D[0], np.finfo(float).tiny) * d * np.finfo(float).eps
    rank = int(np.count_nonzero(D > tol))
    if rank < d - 1:
        raise AlignmentError(
            f"alignment needs a cross-covariance of rank ≥ {d - 1}, got rank {rank} "
            f"(singular values {np.array2string(D, precision=3)}): the positions are collinear or identical")
    S = np.eye(d)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0.0:
        S[-1, -1] = -1.0  # Eq. 43: a rotation, not a reflection
    R = U @ S @ Vt  # Eq. 40
    t = mu_y - R @ mu_x  # Eq. 41
    return R, t


def ate_rmse(tum_gt, tum_est) -> float:
    """Absolute trajectory error (SPEC 7), m.

    The estimated positions are aligned rigidly (no scale) to the ground truth
    by :func:`umeyama_alignment`; ATE = sqrt( (1/n) Σ_i ‖p_i^gt − (R p_i^est + t)‖² ).

    Parameters
    ----------
    tum_gt, tum_est : array_like, shape (n, 8)
        Associated TUM rows (ground truth, estimate).
    """
    gt, est = _check_pair(tum_gt, tum_est)
    R, t = umeyama_alignment(est[:, 1:4], gt[:, 1:4])
    diff = gt[:, 1:4] - (est[:, 1:4] @ R.T + t)
    return float(np.sqrt(np.mean(np.sum(diff * diff, axis=1))))


def se3_from_tum(rows) -> np.ndarray:
    """Homogeneous poses T_world_body from TUM rows (n, 8): shape (n, 4, 4).

    Quaternions are in x, y, z, w order and normalised before use.
    """
    from scipy.spatial.transform import Rotation  # here: ~0.1 s of start-up that only TUM poses need

    a = check_tum(rows)
    T = np.zeros((a.shape[0], 4, 4))
    T[:, :3, :3] = Rotation.from_quat(a[:, 4:8]).as_matrix()
    T[:, :3, 3] = a[:, 1:4]
    T[:, 3, 3] = 1.0
    return T


def relative_translation_errors(tum_gt, tum_est, delta: int = 1) -> np.ndarray:
    """Translational norms of the relative pose errors over ``delta`` frames, m; shape (n − δ,).

    For every i with i + δ < n: E_i = (Q_i⁻¹ Q_{i+δ})⁻¹ (P_i⁻¹ P_{i+δ}), with Q the
    ground-truth and P the estimated poses (full 3D, SPEC 7); the error is
    ‖trans(E_i)‖. No alignment is applied.
    """
    gt, est = _check_pair(tum_gt, tum_est)
    if isinstance(delta, bool) or not isinstance(delta, (int, np.integer)) or delta < 1:
        raise ValueError(f"delta: expected an integer ≥ 1, got {delta!r}")
    n = gt.shape[0]
    if n <= delta:
        raise ValueError(f"delta: need more than delta = {delta} poses, got {n}")
    Q, P = se3_from_tum(gt), se3_from_tum(est)
    Q_rel = invert_pose(Q[:-delta]) @ Q[delta:]
    P_rel = invert_pose(P[:-delta]) @ P[delta:]
    E = invert_pose(Q_rel) @ P_rel
    return np.linalg.norm(E[:, :3, 3], axis=1)


def rpe_rmse(tum_gt, tum_est, delta: int = 1) -> float:
    """Relative pose error (SPEC 7), m: RMSE of :func:`relative_translation_errors`.

    Uses every pair (i, i + δ) (evo's ``all_pairs=True``; for δ = 1 the same as
    evo's default consecutive pairs).
    """
    e = relative_translation_errors(tum_gt, tum_est, delta)
    return float(np.sqrt(np.mean(e * e)))


# ------------------------------------------------------------------ structure errors
# The joint-axis errors axis_angle_deg and axis_line_distance (SPEC 7) are defined in
# stslam.geometry (the hinge-axis fit uses them too) and re-exported here.

def centre_error(centre_hat, centre) -> float:
    """L2 distance ‖ĉ − c‖ between estimated and true centres (any dimension), m (SPEC 7)."""
    a, b = np.asarray(centre_hat, dtype=float), np.asarray(centre, dtype=float)
    if a.shape != b.shape or a.ndim != 1:
        raise ValueError(f"centres must be vectors of the same shape, got {a.shape} and {b.shape}")
    return float(np.linalg.norm(a - b))


def radius_error(radius_hat, radius) -> float:
    """|r̂ − r|, m (SPEC 7)."""
    return float(abs(float(radius_hat) - float(radius)))
