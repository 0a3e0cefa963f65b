"""Figures of the dynamic-world SLAM experiment (SPEC 8.4, paper §VII-D, Table II)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure


def trajectories_figure(poses_true, estimates: dict, landmark_tracks, title: str = "") -> Figure:
    """Top view: ground-truth robot path, every filter's estimate, and the true landmark tracks.

    Parameters
    ----------
    poses_true : numpy.ndarray, shape (n, 3)
        True robot poses (x m, y m, θ rad), world frame.
    estimates : dict[str, numpy.ndarray]
        Method name → estimated poses, shape (n, 3).
    landmark_tracks : numpy.ndarray, shape (n, L, 3)
        True landmark positions per frame (m); static ones draw as dots,
        moving ones as lines.
    """
    figure = Figure(figsize=(6.0, 5.6), layout="constrained")
    axes = figure.subplots()
    tracks = np.asarray(landmark_tracks, dtype=float)
    moving = np.ptp(tracks, axis=0).max(axis=1) > 1e-9
    still = tracks[0, ~moving]
    axes.plot(still[:, 0], still[:, 1], "s", color="0.55", markersize=4, label="static landmark")
    for j in np.flatnonzero(moving):
        axes.plot(tracks[:, j, 0], tracks[:, j, 1], "-", color="tab:red", linewidth=0.8, alpha=0.6,
                  label="moving landmark" if j == np.flatnonzero(moving)[0] else None)
    axes.plot(poses_true[:, 0], poses_true[:, 1], "-", color="black", linewidth=2.2, label="ground truth")
    for i, (method, poses) in enumerate(estimates.items()):
        axes.plot(poses[:, 0], poses[:, 1], "-", color=f"C{i}", linewidth=1.2, label=method)
    axes.plot(poses_true[0, 0], poses_true[0, 1], "o", color="black", markersize=5)
    axes.set_aspect("equal", adjustable="datalim")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.legend(loc="best", fontsize=7)
    if title:
        axes.set_title(title, fontsize=10)
    return figure


def metric_boxplot(metrics: pd.DataFrame, metric: str = "ate_m", label: str = "ATE (m)",
                   paper: dict | None = None) -> Figure:
    """Per-seed values of ``metric`` per method (box plot with the seeds as dots).

    Parameters
    ----------
    metrics : pandas.DataFrame
        One row per seed and method (``metrics.csv``).
    paper : dict[str, float], optional
        The paper's single value per method, drawn as a cross.
    """
    figure = Figure(figsize=(6.0, 3.6), layout="constrained")
    axes = figure.subplots()
    methods = list(pd.unique(metrics["method"]))
    data = [metrics.loc[metrics["method"] == m, metric].to_numpy(dtype=float) for m in methods]
    axes.boxplot(data, showfliers=False)
    axes.set_xticks(np.arange(1, len(methods) + 1), methods)
    jitter = np.random.default_rng(0)  # fixed: the dots' spread is cosmetic and must be reproducible
    labelled = False
    for i, values in enumerate(data, start=1):
        axes.plot(i + jitter.uniform(-0.12, 0.12, values.size), values, ".", color=f"C{i - 1}",
                  alpha=0.6, markersize=4)
        if paper and methods[i - 1] in paper:
            axes.plot(i, paper[methods[i - 1]], "x", color="black", markersize=8,
                      label=None if labelled else "paper (one run)")
            labelled = True
    axes.set_yscale("log")
    axes.set_ylabel(label)
    if labelled:
        axes.legend(loc="best", fontsize=7)
    return figure


def nees_over_time_figure(frames, mean_nees: dict, band: tuple[float, float], title: str = "") -> Figure:
    """Robot NEES per frame averaged over the seeds, per method, with its 95% χ² band (SPEC 6.4).

    Parameters
    ----------
    frames : array_like, shape (n,)
        Frame indices.
    mean_nees : dict[str, numpy.ndarray]
        Method → NEES (n,) averaged over the seeds at each frame.
    band : (float, float)
        The band a consistent filter's average stays in on ~95% of frames.
    """
    figure = Figure(figsize=(6.0, 3.4), layout="constrained")
    axes = figure.subplots()
    axes.axhspan(band[0], band[1], color="0.85", label="95% band")
    axes.axhline(3.0, color="0.5", linewidth=0.8)
    for i, (method, values) in enumerate(mean_nees.items()):
        axes.plot(frames, values, color=f"C{i}", linewidth=1.0, label=method)
    axes.set_yscale("log")
    axes.set_xlabel("frame")
    axes.set_ylabel("robot NEES, mean over seeds")
    axes.set_title(title, fontsize=9)
    axes.legend(loc="upper left", fontsize=7, ncol=3)
    return figure
