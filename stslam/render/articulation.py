"""Figures of articulation model selection (SPEC 8.3, paper Fig. "results_articulation_estimation").

Colours follow the paper: static red, prismatic green, revolute blue; a
landmark is drawn in the μ-weighted mix of its models' colours.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

MODEL_COLOURS = {"static": (0.85, 0.1, 0.1), "prismatic": (0.1, 0.65, 0.1), "revolute": (0.1, 0.25, 0.9)}
UNDECIDED_COLOUR = (0.5, 0.5, 0.5)


def mixed_colour(mu, names) -> tuple[float, float, float]:
    """Σ_j μ_j · colour_j (RGB in [0, 1]); grey when μ is unknown (before the fit)."""
    if mu is None or not np.all(np.isfinite(mu)):
        return UNDECIDED_COLOUR
    rgb = sum(float(m) * np.array(MODEL_COLOURS[n]) for m, n in zip(mu, names))
    return tuple(float(c) for c in np.clip(rgb, 0.0, 1.0))


def frames_figure(snapshots: list[dict], names, sensor_xy=None) -> Figure:
    """Top view (x, y in m, world frame) of the landmarks at a few frames.

    Parameters
    ----------
    snapshots : list of dict
        One per panel: ``{"frame": t, "landmarks": {label: {"trail": (m, 3),
        "mu": (r,) or None, "prediction": (k, 3) or None}}}``. The trail is
        what was observed up to frame t; the prediction the next positions
        under the most probable model.
    names : sequence of str
        Model names in the order of every μ.
    sensor_xy : array_like, shape (2,), optional
        Where the static sensor stands.
    """
    figure = Figure(figsize=(3.3 * len(snapshots), 3.6), layout="constrained")
    axes_list = figure.subplots(1, len(snapshots), sharex=True, sharey=True, squeeze=False)[0]
    for axes, snap in zip(axes_list, snapshots):
        for label, item in snap["landmarks"].items():
            trail = np.asarray(item["trail"])
            colour = mixed_colour(item["mu"], names)
            axes.plot(trail[:, 0], trail[:, 1], ".", color=colour, alpha=0.3, markersize=3)
            axes.plot(trail[-1, 0], trail[-1, 1], "o", color=colour, markersize=9, markeredgecolor="k")
            axes.annotate(label, trail[-1, :2], textcoords="offset points", xytext=(6, 6), fontsize=7)
            if item.get("prediction") is not None and len(item["prediction"]):
                pred = np.asarray(item["prediction"])
                axes.plot(np.r_[trail[-1, 0], pred[:, 0]], np.r_[trail[-1, 1], pred[:, 1]], "--",
                          color=colour, linewidth=1.2)
        if sensor_xy is not None:
            axes.plot(*sensor_xy, "k^", markersize=8)
        axes.set_title(f"t = {snap['frame']}")
        axes.set_xlabel("x (m)")
        axes.set_aspect("equal", adjustable="box")
        axes.grid(alpha=0.3)
    axes_list[0].set_ylabel("y (m)")
    handles = [axes_list[0].plot([], [], "o", color=MODEL_COLOURS[n], label=n)[0] for n in names]
    figure.legend(handles=handles, loc="outside lower center", ncol=len(names), fontsize="small")
    return figure


def mu_history_figure(histories: dict[str, np.ndarray], names, tau: float) -> Figure:
    """μ over frames per landmark: median over seeds and the 10–90% band of each model.

    ``histories`` maps a landmark label to an array (n_seeds, n_frames, r);
    NaN before selection starts.
    """
    figure = Figure(figsize=(3.4 * len(histories), 3.0), layout="constrained")
    axes_list = figure.subplots(1, len(histories), sharey=True, squeeze=False)[0]
    for axes, (label, mu) in zip(axes_list, histories.items()):
        frames = np.arange(mu.shape[1])
        started = ~np.all(np.isnan(mu[:, :, 0]), axis=0)
        for j, name in enumerate(names):
            values = mu[:, started, j]
            axes.plot(frames[started], np.median(values, axis=0), color=MODEL_COLOURS[name], label=name)
            if mu.shape[0] > 1:
                low, high = np.percentile(values, [10, 90], axis=0)
                axes.fill_between(frames[started], low, high, color=MODEL_COLOURS[name], alpha=0.15)
        axes.axhline(tau, color="k", linestyle=":", linewidth=1)
        axes.set_title(f"{label} landmark")
        axes.set_xlabel("frame")
        axes.set_ylim(-0.02, 1.02)
        axes.grid(alpha=0.3)
    axes_list[0].set_ylabel("μ (median, 10–90% over seeds)")
    axes_list[-1].legend(fontsize="small")
    return figure


def table_figure(table: pd.DataFrame, title: str) -> Figure:
    """A small table drawn as a figure (numbers rounded to 3 significant digits)."""
    text = [[f"{v:.3g}" if isinstance(v, (float, np.floating)) else str(v) for v in row]
            for row in table.itertuples(index=False)]
    figure = Figure(figsize=(1.0 * len(table.columns) + 0.5, 0.3 * len(table) + 0.8), layout="constrained")
    axes = figure.add_subplot()
    axes.axis("off")
    axes.set_title(title, fontsize="medium")
    axes.table(cellText=text, colLabels=list(table.columns), loc="center").auto_set_font_size(True)
    return figure
