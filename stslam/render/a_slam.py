"""Figures of A-SLAM's model selection inside SLAM (SPEC 4, 6.3, 8.4)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from stslam.render.articulation import MODEL_COLOURS


def model_probabilities_figure(panels, title: str = "") -> Figure:
    """Model probabilities μ over time for a few landmarks, one panel each.

    Parameters
    ----------
    panels : list of dict
        Each ``{"label": str, "frames": (n,) int, "mu": (n, r), "names": (r,) str,
        "decisions": [(frame, step, model), …]}``: the frames at which the
        landmark's selector received an observation, μ after each (NaN rows
        before selection started), the model names, and A-SLAM's decisions
        (drawn as vertical lines in the chosen model's colour).
    title : str
        Figure title.
    """
    figure = Figure(figsize=(6.4, 1.9 * max(len(panels), 1) + 0.4), layout="constrained")
    axes_list = np.atleast_1d(figure.subplots(max(len(panels), 1), 1, sharex=True))
    for axes, panel in zip(axes_list, panels):
        frames = np.asarray(panel["frames"])
        mu = np.asarray(panel["mu"], dtype=float).reshape(frames.size, -1)
        for j, name in enumerate(panel["names"]):
            axes.plot(frames, mu[:, j], ".-", color=MODEL_COLOURS.get(name, f"C{j}"), linewidth=1.0,
                      markersize=3, label=name)
        for frame, _, model in panel.get("decisions", ()):
            axes.axvline(frame, color=MODEL_COLOURS.get(model, "k"), linestyle="--", linewidth=0.8)
        axes.set_ylim(-0.03, 1.03)
        axes.set_ylabel("μ")
        axes.set_title(panel["label"], fontsize=9)
    axes_list[-1].set_xlabel("frame")
    axes_list[0].legend(loc="center right", fontsize=7)
    if title:
        figure.suptitle(title, fontsize=10)
    return figure
