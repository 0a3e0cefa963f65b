"""What the fridge experiment adds for a user's own recording (SPEC 15): missing-metric reasons, structures.

A recording may lack the true robot poses or the door's ground truth
(:class:`stslam.rgbd.tracks.SequenceTracks` ``has_ground_truth`` /
``has_door_truth``): the metrics that need them are NaN, and
:func:`not_computed` says which and why. :func:`structure_table` lists the
articulated structures A-SLAM found, whether or not there is truth to score
them against.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from stslam.articulation.models import get_model
from stslam.errors import DegenerateFitError
from stslam.rgbd.tracks import world_points

POSE_METRICS = ("ate_m", "rpe_m", "nees", "axis_angle_deg_true_poses", "axis_dist_m_true_poses")
DOOR_METRICS = ("axis_angle_deg", "axis_dist_m", "axis_angle_deg_true_poses", "axis_dist_m_true_poses")
STRUCTURE_COLUMNS = ("seed", "kind", "landmark", "model", "body", "point_x", "point_y", "point_z", "dir_x",
                     "dir_y", "dir_z", "radius_m", "residual_m", "n_points")


def not_computed(tracks) -> dict[str, str]:
    """Metric → why it is NaN for this recording (empty when it holds all the truth)."""
    reasons = {}
    if not tracks.has_door_truth:
        for name in DOOR_METRICS:
            reasons[name] = "the recording has no door ground truth"
    if not tracks.has_ground_truth:
        for name in POSE_METRICS:
            reasons[name] = "the recording has no ground-truth robot pose"
    return reasons


def not_computed_lines(reasons_by_seed: dict[int, dict[str, str]]) -> list[str]:
    """One summary line per reason: which metrics are NaN (and on which seeds)."""
    by_reason: dict[str, list[str]] = {}
    for reasons in reasons_by_seed.values():
        for metric, reason in reasons.items():
            if metric not in by_reason.setdefault(reason, []):
                by_reason[reason].append(metric)
    return [f"not computed (NaN): {', '.join(metrics)}: {reason}" for reason, metrics in by_reason.items()]


def not_computed_table(reasons_by_seed: dict[int, dict[str, str]]) -> pd.DataFrame:
    """``not_computed.csv``: one row (seed, metric, reason) per NaN metric."""
    rows = [{"seed": seed, "metric": metric, "reason": reason}
            for seed, reasons in reasons_by_seed.items() for metric, reason in reasons.items()]
    return pd.DataFrame(rows, columns=["seed", "metric", "reason"])


def _row(seed, kind, landmark, model, body, point, direction, radius, residual, n) -> dict:
    point = np.full(3, np.nan) if point is None else np.asarray(point, dtype=float)
    direction = np.full(3, np.nan) if direction is None else np.asarray(direction, dtype=float)
    return dict(zip(STRUCTURE_COLUMNS, (seed, kind, landmark, model, body, *point, *direction, radius, residual, n),
                    strict=True))


def structure_table(seed: int, tracks, poses_xytheta, landmarks: dict, hinge_axis) -> pd.DataFrame:
    """Articulated structures of one run, world frame (m), from A-SLAM's poses.

    One ``landmark`` row per landmark A-SLAM holds prismatic (line point and
    direction) or revolute (axis point = circle centre, axis direction,
    radius), fitted to its track mapped with ``poses_xytheta``; one ``axis``
    row for the hinge axis shared by the revolute tracks (``body`` 0, its
    members carry the same body number; −1 for tracks outside it).
    """
    members = set(hinge_axis.member_ids) if hinge_axis is not None else set()
    rows = []
    for i, report in sorted(landmarks.items()):
        if report.model not in ("prismatic", "revolute"):
            continue
        ks, z, _ = tracks.track_robot(i)
        points = world_points(poses_xytheta, ks, z)
        body = 0 if i in members else -1
        try:
            s = get_model(report.model).fit(points)
        except DegenerateFitError:
            rows.append(_row(seed, "landmark", i, report.model, body, None, None, np.nan, np.nan, len(points)))
            continue
        if report.model == "prismatic":
            rows.append(_row(seed, "landmark", i, "prismatic", body, s.p0, s.direction, np.nan, s.residual_m,
                             len(points)))
        else:
            rows.append(_row(seed, "landmark", i, "revolute", body, s.axis_point, s.axis_direction, s.radius,
                             s.residual_m, len(points)))
    if hinge_axis is not None:
        rows.append(_row(seed, "axis", -1, "revolute", 0, hinge_axis.point_world, hinge_axis.direction_world,
                         np.nan, np.nan, len(members)))
    return pd.DataFrame(rows, columns=list(STRUCTURE_COLUMNS))
