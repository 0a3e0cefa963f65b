"""Figures of A-SLAM's model selection inside SLAM (SPEC 4, 6.3, 8.4)."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from stslam.render.articulation import MODEL_COLOURS
from stslam.slam.decision_scores import judged_rows


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


def decision_times_figure(decisions, title: str = "") -> Figure:
    """When A-SLAM's decisions about the movers seen moving were made (``decisions.csv`` rows,
    :func:`stslam.slam.decision_scores.decision_rows`): the frame of each first articulated decision,
    stacked by whether it was the true model, and the frame at which the true model was first chosen."""
    judged = judged_rows(decisions)
    movers = judged[judged["true_model"] != "static"]
    fig = Figure(figsize=(6.4, 3.4))
    ax = fig.add_subplot()
    first = movers.dropna(subset=["first_frame"])
    right = first["first_model"] == first["true_model"]
    frames = [first.loc[right, "first_frame"], first.loc[~right, "first_frame"]]
    top = max([1.0, *[float(f.max()) for f in frames if len(f)], *movers["right_frame"].dropna().tolist()])
    bins = np.linspace(0.0, top + 1.0, 34)
    ax.hist(frames, bins=bins, stacked=True, color=["tab:green", "tab:red"],
            label=[f"first decision right ({len(frames[0])})", f"first decision wrong ({len(frames[1])})"])
    ax.hist(movers["right_frame"].dropna(), bins=bins, histtype="step", color="black",
            label=f"true model first chosen ({movers['right_frame'].notna().sum()} of {len(movers)})")
    ax.set_xlabel("frame")
    ax.set_ylabel("moving points")
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title)
    fig.tight_layout()
    return fig
