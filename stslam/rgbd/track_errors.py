"""How far a recording's feature tracks are from the white noise the filters assume (needs ground truth).

Each observation z (robot frame) of a track is mapped to the world with the
true robot pose, m = R(θ) z + [x, y, 0]ᵀ (SPEC 5.2), and its covariance with
it, R(θ) R_z R(θ)ᵀ. A point on the door is then turned back about the true
hinge by the door's true angle (into the frame of the closed door), so that a
point that stays put, on the wall or on the door, keeps one position. A track
is counted as the door's when that makes its points spread less than they do
in the world frame.

The residuals of a track from its mean position, whitened by each
observation's covariance (r = L⁻¹(m − m̄), L Lᵀ the covariance), would be
independent standard normals if the front end's covariance said everything
about its errors: a mean NIS rᵀr of 3 and no correlation between frames.
Tracked features on real or rendered images drift instead (a corner slides
by a fraction of a pixel, a depth window sees a little more of a slanted
surface as the view turns), and the drift persists: the correlation of the
whitened residuals of frames k and k + lag tells for how long. A filter or a
smoother that reads such a track at every frame counts one error as many
(``isam2.observe_every``, :func:`stslam.slam.loop.run_slam`).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from stslam.geometry import rotation_about_axis, rotation_z
from stslam.robot.sensor import point_from_observation

__all__ = ["DEFAULT_LAGS", "track_error_table", "track_error_summary"]

DEFAULT_LAGS = (1, 5, 15, 30)  # frames; 30 is one second at 30 Hz
MIN_PAIRS = 10  # a lag with fewer pairs of frames in a track gets no correlation (NaN)


def _world_observations(tracks, track_ids) -> dict:
    """Track id → (frame indices, world points (n, 3), world covariances (n, 3, 3)), with the true poses."""
    wanted = {int(i): ([], [], []) for i in track_ids}
    for k in range(tracks.n_frames):
        ids, zs, Rs = tracks.observations_robot(k)
        pose = tracks.poses_gt_xytheta[k]
        rot = rotation_z(pose[2])
        for i, z, R in zip(np.asarray(ids, dtype=int), zs, Rs, strict=True):
            if int(i) in wanted:
                frames, points, covs = wanted[int(i)]
                frames.append(k)
                points.append(point_from_observation(pose, z)[0])
                covs.append(rot @ R @ rot.T)
    return {i: (f, np.array(p).reshape(-1, 3), np.array(c).reshape(-1, 3, 3)) for i, (f, p, c) in wanted.items()}


def _spread(points: np.ndarray) -> float:
    """RMS distance (m) of points (n, 3) from their mean."""
    return float(np.sqrt(np.mean(np.sum((points - points.mean(axis=0)) ** 2, axis=1))))


def _whitened(points: np.ndarray, covs: np.ndarray) -> np.ndarray:
    """L⁻¹(m − m̄) of each point, L the Cholesky factor of its covariance: (n, 3)."""
    residuals = points - points.mean(axis=0)
    return np.array([np.linalg.solve(np.linalg.cholesky(C), r) for r, C in zip(residuals, covs, strict=True)])


def _lag_correlation(frames: list, white: np.ndarray, lag: int) -> float:
    """Correlation of the whitened residuals (every coordinate) of frames k and k + lag, over the track."""
    at = {k: n for n, k in enumerate(frames)}
    pairs = [(n, at[k + lag]) for n, k in enumerate(frames) if k + lag in at]
    if len(pairs) < MIN_PAIRS:
        return float("nan")
    first, second = (white[[p[i] for p in pairs]].ravel() for i in (0, 1))
    return float(np.corrcoef(first, second)[0, 1])


def track_error_table(tracks, track_ids, lags=DEFAULT_LAGS) -> pd.DataFrame:
    """One row per track of ``track_ids``: ``track``, ``kind`` (static or door), ``n``, ``spread_m``
    (RMS distance from its mean position, in the frame that keeps it put), ``mean_nis`` and
    ``corr_lag<L>`` per lag (module docstring).

    ``tracks`` is a :class:`~stslam.rgbd.tracks.SequenceTracks` with the true robot poses and the door's
    ground truth; without them there is nothing to compare with, and the table is empty.
    """
    columns = ["track", "kind", "n", "spread_m", "mean_nis", *[f"corr_lag{lag}" for lag in lags]]
    if not (tracks.has_ground_truth and tracks.has_door_truth):
        return pd.DataFrame(columns=columns)
    hinge = np.asarray(tracks.hinge_point_world, dtype=float)
    axis = np.asarray(tracks.hinge_axis_world, dtype=float)
    axis = axis / np.linalg.norm(axis)
    rows = []
    for track_id, (frames, points, covs) in _world_observations(tracks, track_ids).items():
        if len(frames) < 2:
            continue
        turns = [rotation_about_axis(axis, -float(tracks.door_angles_rad[k])) for k in frames]
        on_door = np.array([hinge + T @ (m - hinge) for T, m in zip(turns, points, strict=True)])
        door_covs = np.array([T @ C @ T.T for T, C in zip(turns, covs, strict=True)])
        is_door = _spread(on_door) < _spread(points)
        points, covs = (on_door, door_covs) if is_door else (points, covs)
        white = _whitened(points, covs)
        rows.append({"track": int(track_id), "kind": "door" if is_door else "static", "n": len(frames),
                     "spread_m": _spread(points), "mean_nis": float(np.mean(np.sum(white**2, axis=1))),
                     **{f"corr_lag{lag}": _lag_correlation(frames, white, lag) for lag in lags}})
    return pd.DataFrame(rows, columns=columns)


def track_error_summary(table: pd.DataFrame) -> list[str]:
    """Printed lines: per kind of track, the median mean NIS and the median correlation at each lag."""
    lags = [c for c in table.columns if c.startswith("corr_lag")]
    lines = []
    for kind, group in table.groupby("kind", sort=True):
        corr = ", ".join(f"{c.removeprefix('corr_lag')}: {group[c].median():.2f}" for c in lags)
        lines.append(f"track errors, {kind} ({len(group)} tracks): median NIS {group['mean_nis'].median():.1f} "
                     f"(3 if white with the front end's R); correlation at lags (frames) {corr}")
    return lines
