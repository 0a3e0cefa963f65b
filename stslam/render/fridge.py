"""Figures of the fridge experiment (SPEC 8.5, paper §VII-E and its axis figure)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from stslam.geometry import invert_pose, planar_pose_matrix, transform_points
from stslam.robot.pinhole import project_points
from stslam.render.articulation import MODEL_COLOURS

UNDECIDED_COLOUR = (0.6, 0.6, 0.6)
TRUE_AXIS_HEIGHT_M = (0.0, 1.8)  # the true axis is drawn over this span above its point (m)


def _model_of(report) -> str | None:
    """The landmark's model for display: A-SLAM's model at the end (None while undecided)."""
    return None if report.model == "undecided" else report.model


def _segment_pixels(T_world_camera, K, point_world, direction_world, heights_m):
    """Pixels (2, 2) of the axis segment point + h·direction for h in ``heights_m``; None if behind the camera."""
    ends = np.asarray(point_world)[None, :] + np.outer(heights_m, direction_world)
    uv, z = project_points(K, transform_points(invert_pose(T_world_camera), ends))
    return uv if np.all(z > 0.05) else None


def tracks_axis_figure(tracks, records: dict, axis, title: str = "") -> Figure:
    """One frame with its landmark tracks coloured by model and the hinge axis, estimated over true.

    Parameters
    ----------
    tracks : stslam.rgbd.tracks.SequenceTracks
        Its snapshot frame is drawn; the camera pose is the true one (display only).
    records : dict
        Landmark id → :class:`stslam.slam.a_slam.LandmarkReport`.
    axis : stslam.articulation.hinge_axis.HingeAxis or None
    """
    k = tracks.snapshot_index
    figure = Figure(figsize=(7.0, 5.6), layout="constrained")
    ax = figure.subplots()
    ax.imshow(tracks.snapshot_rgb)
    for i, record in sorted(records.items()):
        frames, pixels = tracks.track_pixels(i)
        upto = frames <= k
        if not upto.any() or frames[upto][-1] != k:
            continue
        model = _model_of(record)
        colour = MODEL_COLOURS.get(model, UNDECIDED_COLOUR)
        trail = pixels[upto][-15:]
        ax.plot(trail[:, 0], trail[:, 1], "-", color=colour, linewidth=1.0, alpha=0.8)
        ax.plot(trail[-1, 0], trail[-1, 1], "o", color=colour, markersize=5, markeredgecolor="k",
                markeredgewidth=0.5)
    T_world_camera = planar_pose_matrix(tracks.poses_gt_xytheta[k]) @ tracks.T_base_camera
    true_uv = _segment_pixels(T_world_camera, tracks.K, tracks.hinge_point_world, tracks.hinge_axis_world,
                              TRUE_AXIS_HEIGHT_M)
    if true_uv is not None:
        ax.plot(true_uv[:, 0], true_uv[:, 1], "--", color="black", linewidth=2.0, label="true hinge axis")
    if axis is not None:
        est_uv = _segment_pixels(T_world_camera, tracks.K, axis.point_world, axis.direction_world,
                                 axis.height_range_m)
        if est_uv is not None:
            ax.plot(est_uv[:, 0], est_uv[:, 1], "-", color="gold", linewidth=2.5, label="estimated axis")
    for name, colour in (*MODEL_COLOURS.items(), ("undecided", UNDECIDED_COLOUR)):
        ax.plot([], [], "o", color=colour, label=name)
    width, height = tracks.image_size
    ax.set_xlim(0, width - 1)
    ax.set_ylim(height - 1, 0)
    ax.set_axis_off()
    ax.legend(loc="lower left", fontsize=7, framealpha=0.8)
    if title:
        ax.set_title(title)
    return figure


def trajectories_figure(poses_true, estimates: dict, hinge_point_world, title: str = "") -> Figure:
    """Top view: true robot path, odometry and every filter's estimate, and the hinge (m, world)."""
    figure = Figure(figsize=(6.0, 5.6), layout="constrained")
    ax = figure.subplots()
    ax.plot(poses_true[:, 0], poses_true[:, 1], "-", color="black", linewidth=2.2, label="ground truth")
    for i, (method, poses) in enumerate(estimates.items()):
        style = ":" if method == "odometry" else "-"
        ax.plot(poses[:, 0], poses[:, 1], style, color=f"C{i}", linewidth=1.2, label=method)
    ax.plot(*hinge_point_world[:2], "^", color="tab:red", markersize=8, label="door hinge")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(loc="best", fontsize=7)
    if title:
        ax.set_title(title)
    return figure


def mu_figure(tracks, records: dict, n_per_model: int = 2) -> Figure:
    """Model probabilities μ over time of a few landmarks: up to ``n_per_model`` per displayed model."""
    chosen = []
    for name in ("revolute", "prismatic", "static", None):
        ids = [i for i, r in sorted(records.items()) if _model_of(r) == name and r.mu_frames.size > 0]
        ids.sort(key=lambda i: -records[i].mu_frames.size)
        chosen.extend(ids[:n_per_model])
    figure = Figure(figsize=(7.0, 1.6 * max(len(chosen), 1) + 0.6), layout="constrained")
    axes = np.atleast_1d(figure.subplots(max(len(chosen), 1), 1, sharex=True))
    for ax, i in zip(axes, chosen):
        report = records[i]
        t = tracks.times_s[report.mu_frames]
        for j, name in enumerate(report.model_names):
            ax.plot(t, report.mu[:, j], color=MODEL_COLOURS.get(name, "k"), label=name)
        for frame, _, _ in report.decisions:
            ax.axvline(tracks.times_s[frame], color="k", linestyle=":", linewidth=1)
        ax.set_ylim(-0.05, 1.05)
        ax.set_ylabel("μ")
        ax.set_title(f"track {i}: {report.model}", fontsize=8)
    axes[0].legend(loc="upper right", fontsize=7)
    axes[-1].set_xlabel("time (s)")
    return figure
