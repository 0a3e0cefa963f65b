"""Figures of the speed benchmark."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure


def scaling_figure(sizes, seconds, slope: float) -> Figure:
    """Per-step time against the number of landmarks in the state, log–log, with the fitted slope."""
    sizes = np.asarray(sizes, dtype=float)
    seconds = np.asarray(seconds, dtype=float)
    figure = Figure(figsize=(4.8, 3.4), layout="constrained")
    axes = figure.add_subplot()
    axes.loglog(sizes, 1e3 * seconds, "o-", label=f"measured (slope {slope:.2f})")
    reference = 1e3 * seconds[-1] * (sizes / sizes[-1]) ** 2
    axes.loglog(sizes, reference, "--", color="grey", label="O(n²) through the last point")
    axes.set_xlabel("landmarks in the state")
    axes.set_ylabel("time per step (ms)")
    axes.grid(alpha=0.3, which="both")
    axes.legend(fontsize="small")
    return figure


def step_time_figure(step_times: dict) -> Figure:
    """Median per-step time of each filter (bar chart, ms)."""
    names = list(step_times)
    figure = Figure(figsize=(4.8, 3.0), layout="constrained")
    axes = figure.add_subplot()
    axes.bar(names, [1e3 * step_times[n] for n in names], color="tab:blue")
    axes.set_ylabel("time per step (ms)")
    axes.tick_params(axis="x", labelrotation=20)
    axes.grid(alpha=0.3, axis="y")
    return figure
