"""Preview of the fridge-door RGB-D sequence (SPEC 9): sample frames, door angle, robot paths."""

from __future__ import annotations

import matplotlib
import numpy as np
from matplotlib.figure import Figure


def sequence_preview(sample_times_s, sample_rgb, sample_depth_m, times_s, door_angles_rad, poses_gt_xytheta,
                     poses_odom_xytheta, hinge_point_world, max_depth_m: float = 4.0) -> Figure:
    """Figure: RGB above depth for a few frames, then the door angle over time and the robot paths.

    Parameters
    ----------
    sample_times_s : sequence of float, length m
        Times of the sample frames (s).
    sample_rgb : sequence of numpy.ndarray (H, W, 3) uint8, length m
    sample_depth_m : sequence of numpy.ndarray (H, W) float32, length m
        Depth (m), NaN = no return (drawn black).
    times_s : numpy.ndarray, shape (n,)
    door_angles_rad : numpy.ndarray, shape (n,)
    poses_gt_xytheta, poses_odom_xytheta : numpy.ndarray, shape (n, 3)
        Ground-truth and odometry robot poses (m, m, rad).
    hinge_point_world : numpy.ndarray, shape (3,)
        Door hinge (m), marked on the top view.
    max_depth_m : float
        Top of the depth colour scale (m).
    """
    m = len(sample_rgb)
    fig = Figure(figsize=(3.0 * m, 8.0), layout="constrained")
    grid = fig.add_gridspec(3, m, height_ratios=[1.0, 1.0, 1.2])
    image = None
    for j in range(m):
        ax = fig.add_subplot(grid[0, j])
        ax.imshow(sample_rgb[j])
        ax.set_title(f"t = {sample_times_s[j]:.2f} s", fontsize=9)
        ax.set_axis_off()
        ax = fig.add_subplot(grid[1, j])
        depth = np.ma.masked_invalid(sample_depth_m[j])
        image = ax.imshow(depth, cmap=matplotlib.colormaps["viridis"].with_extremes(bad="black"), vmin=0.0,
                          vmax=max_depth_m)
        ax.set_axis_off()
    if image is not None:
        fig.colorbar(image, ax=fig.axes[1::2], shrink=0.8, label="depth (m); black = no return")

    half = max(1, m // 2)
    ax = fig.add_subplot(grid[2, :half])
    ax.plot(times_s, np.rad2deg(door_angles_rad), color="tab:blue")
    for t in sample_times_s:
        ax.axvline(t, color="0.6", linewidth=0.8, linestyle=":")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("door angle (deg)")
    ax.set_title("door opening (ground truth)", fontsize=9)

    ax = fig.add_subplot(grid[2, half:])
    ax.plot(poses_gt_xytheta[:, 0], poses_gt_xytheta[:, 1], color="black", label="ground truth")
    ax.plot(poses_odom_xytheta[:, 0], poses_odom_xytheta[:, 1], color="tab:orange", linestyle="--",
            label="odometry")
    ax.plot(*hinge_point_world[:2], marker="^", color="tab:red", linestyle="none", label="door hinge")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title("robot path, top view", fontsize=9)
    ax.legend(fontsize=8)
    return fig
