"""Filter consistency: robot-pose NEES against ground truth and its χ² band (SPEC 6.4)."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from stslam.robot import wrap_angle

# Frames left out of the NEES average: the start pose is known exactly (P = 0 at
# frame 0) and after one step P is V S Vᵀ, rank 2 (two controls drive three
# pose states), so the pose covariance is invertible from frame 2 on.
NEES_FIRST_FRAME = 2


def pose_errors(poses_true, poses_est) -> np.ndarray:
    """Pose errors (x m, y m, θ rad) = true − estimate with θ wrapped to [−π, π), shape (n, 3)."""
    e = np.asarray(poses_true, dtype=float) - np.asarray(poses_est, dtype=float)
    e[:, 2] = wrap_angle(e[:, 2])
    return e


def pose_nees(poses_true, poses_est, pose_covs, first_frame: int = NEES_FIRST_FRAME) -> np.ndarray:
    """NEES eₖᵀ Pₖ⁻¹ eₖ of the robot pose per frame from ``first_frame`` on (SPEC 6.4).

    Parameters
    ----------
    poses_true, poses_est : array_like, shape (n, 3)
        (x m, y m, θ rad), world frame.
    pose_covs : array_like, shape (n, 3, 3)
        Estimated pose covariances, world frame.

    Returns
    -------
    numpy.ndarray, shape (n − first_frame,)
        χ² with 3 degrees of freedom per frame for a consistent filter.
    """
    e = pose_errors(poses_true, poses_est)[first_frame:]
    P = np.asarray(pose_covs, dtype=float)[first_frame:]
    return np.einsum("ni,ni->n", e, np.linalg.solve(P, e[:, :, None])[:, :, 0])


def nees_band(n_steps: int, dof: int = 3, n_runs: int = 1, level: float = 0.95) -> tuple[float, float]:
    """Two-sided ``level`` band of a NEES averaged over ``n_steps`` × ``n_runs`` values.

    For a consistent filter each value is χ²(dof); treating them as independent,
    their sum is χ²(dof·N), N = n_steps·n_runs, so the average lies in
    [χ²_{(1−level)/2}(dof N)/N, χ²_{(1+level)/2}(dof N)/N] with probability ``level``
    (Bar-Shalom, Li, Kirubarajan 2001, §5.4).
    """
    N = n_steps * n_runs
    return (float(chi2.ppf(0.5 - level / 2, dof * N) / N), float(chi2.ppf(0.5 + level / 2, dof * N) / N))
