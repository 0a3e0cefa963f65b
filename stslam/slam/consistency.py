"""Filter consistency: robot-pose NEES against ground truth and its χ² band (SPEC 6.4)."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from stslam.robot.motion import wrap_angle

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
    return chi2_mean_band(n_steps * n_runs, dof, level)


def chi2_mean_band(n_values: float, dof: int = 3, level: float = 0.95) -> tuple[float, float]:
    """Two-sided ``level`` band of the mean of ``n_values`` independent χ²(dof) values (may be fractional):
    [χ²_{(1−level)/2}(dof N)/N, χ²_{(1+level)/2}(dof N)/N]."""
    N = float(n_values)
    return (float(chi2.ppf(0.5 - level / 2, dof * N) / N), float(chi2.ppf(0.5 + level / 2, dof * N) / N))


def autocorrelation_time(series) -> float:
    """Integrated autocorrelation time τ = 1 + 2 Σ_{l≥1} ρ_l of runs of one stationary series.

    ``series`` (n_runs, n_steps): the runs are independent, the steps of a
    run are not. ρ_l is pooled over the runs around the grand mean; the sum is
    cut by Geyer's initial positive sequence (pairs ρ_{2m} + ρ_{2m+1} summed
    while positive; Geyer 1992, Statistical Science 7(4)), the usual rule for
    MCMC effective sample sizes. τ ≥ 1; n_steps/τ is the number of
    effectively independent steps per run.
    """
    a = np.asarray(series, dtype=float)
    if a.ndim != 2 or a.shape[1] < 2 or not np.all(np.isfinite(a)):
        raise ValueError(f"series: expected finite values of shape (n_runs, n_steps ≥ 2), got shape {a.shape}")
    n_steps = a.shape[1]
    a = a - a.mean()
    variance = float(np.mean(a * a))
    if variance == 0.0:
        return 1.0
    rho = np.array([np.mean(a[:, :n_steps - lag] * a[:, lag:]) for lag in range(n_steps)]) / variance
    total = 0.0
    for m in range(n_steps // 2):
        pair = rho[2 * m] + rho[2 * m + 1]
        if pair <= 0.0:
            break
        total += pair
    return max(1.0, 2.0 * total - 1.0)  # 2 Σ pairs counts ρ_0 twice: τ = 2 Σ − ρ_0


def nees_band_correlated(nees_per_frame, dof: int = 3, level: float = 0.95) -> tuple[float, float, float]:
    """Two-sided ``level`` band of the NEES averaged over frames and runs, frames autocorrelated.

    :func:`nees_band` treats every frame as an independent χ²(dof) draw. A
    filter's pose errors persist over many frames (a map error carries into
    every later pose), so the average of N = n_runs · n_steps frames varies as
    much as that of N/τ independent ones (τ: :func:`autocorrelation_time` of
    the NEES series). The band is then :func:`nees_band` with N/τ values, the
    χ² whose mean and variance match (Satterthwaite's approximation); for
    τ = 1 it is :func:`nees_band`. τ is a ratio of the series to itself, so a
    filter that is overconfident by a constant factor gets the same τ as a
    consistent one: the band's width does not follow the NEES's level.

    Parameters
    ----------
    nees_per_frame : array_like, shape (n_runs, n_steps)

    Returns
    -------
    (low, high, tau)
    """
    nees = np.asarray(nees_per_frame, dtype=float)
    tau = autocorrelation_time(nees)
    return (*chi2_mean_band(nees.size / tau, dof, level), tau)
