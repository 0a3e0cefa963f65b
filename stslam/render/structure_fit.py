"""Figures of the structure-fit experiment (SPEC 8.1, paper §VII-A figure and Table I)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure

METHOD_STYLE = {
    "separate": {"color": "tab:blue", "marker": "o", "label": "separate (circle fit)"},
    "joint": {"color": "tab:orange", "marker": "s", "label": "joint (constant rate)"},
    "crb": {"color": "black", "linestyle": "--", "label": "CRB, angles unknown"},
    "crb_joint": {"color": "grey", "linestyle": ":", "label": "CRB, constant rate"},
}


def _circle(centre, radius, n=361):
    a = np.linspace(0.0, 2.0 * np.pi, n)
    return centre[0] + radius * np.cos(a), centre[1] + radius * np.sin(a)


def single_run_figure(points_xy, joint_idx, fits: dict, centre, radius, protocol: str) -> Figure:
    """One Monte Carlo run: samples, the true circle and both fitted circles.

    Parameters
    ----------
    points_xy : numpy.ndarray, shape (n, 2)
        Noisy samples (m).
    joint_idx : numpy.ndarray of int
        Samples the joint fit used (circled).
    fits : dict[str, tuple[numpy.ndarray (2,), float]]
        Method name to fitted centre (m) and radius (m).
    centre, radius : array (2,), float
        The true circle (m).
    protocol : str
        Shown in the title.
    """
    figure = Figure(figsize=(4.8, 4.6), layout="constrained")
    axes = figure.add_subplot()
    axes.plot(*_circle(centre, radius), color="black", lw=1.2, label="truth")
    axes.plot(*centre, "k+", ms=10)
    for method in ("separate", "joint"):
        c, r = fits[method]
        if np.all(np.isfinite(c)) and np.isfinite(r):
            style = METHOD_STYLE[method]
            axes.plot(*_circle(c, r), color=style["color"], lw=1.2, label=style["label"])
            axes.plot(*c, marker="x", color=style["color"], ms=8)
    axes.plot(points_xy[:, 0], points_xy[:, 1], "o", color="tab:red", ms=5, label="samples")
    used = np.asarray(joint_idx)
    if used.size < points_xy.shape[0]:
        axes.plot(points_xy[used, 0], points_xy[used, 1], "o", mfc="none", mec="tab:orange", ms=10,
                  label="samples of the joint fit")
    axes.set_aspect("equal")
    axes.set_xlabel("x (m)")
    axes.set_ylabel("y (m)")
    axes.set_title(f"One run, {protocol} protocol")
    axes.grid(alpha=0.3)
    axes.legend(fontsize="x-small", loc="best")
    return figure


def sweep_figure(sweep: pd.DataFrame, n_samples: int, arc_deg: float, sigma: float) -> Figure:
    """Centre and radius RMSE against arc length and sample count, with both CRBs.

    ``sweep`` has columns ``swept`` ("arc_deg" or "n_samples"), ``arc_deg``,
    ``n_samples``, ``method``, ``centre_rmse``, ``radius_rmse`` (m).
    """
    figure = Figure(figsize=(8.0, 6.0), layout="constrained")
    grid = figure.subplots(2, 2, squeeze=False)
    panels = [("arc_deg", "arc (deg)", f"n = {n_samples}"), ("n_samples", "samples n", f"arc = {arc_deg:g}°")]
    for col, (swept, xlabel, fixed) in enumerate(panels):
        block = sweep[sweep["swept"] == swept]
        for row, metric in enumerate(("centre_rmse", "radius_rmse")):
            axes = grid[row, col]
            bound = block[block["method"] == "crb"][metric].to_numpy(dtype=float)
            if bound.size == 0:
                continue
            # Short arcs give wild fits (the fits have no finite moments there), so the
            # axis is fitted to the bounds and values above it are drawn at the top edge.
            low, high = 0.5 * bound.min(), 8.0 * bound.max()
            for method, style in METHOD_STYLE.items():
                part = block[block["method"] == method].sort_values(swept)
                if part.empty:
                    continue
                values = part[metric].to_numpy(dtype=float)
                axes.plot(part[swept], np.minimum(values, high), **style)
                off = values > high
                if np.any(off):
                    axes.plot(part[swept].to_numpy()[off], np.full(off.sum(), high), "^",
                              color=style["color"], ms=9, clip_on=False)
            axes.set_yscale("log")
            axes.set_ylim(low, high)
            if swept == "n_samples":
                axes.set_xscale("log")
                ticks = sorted(pd.unique(block["n_samples"]))
                axes.set_xticks(ticks, [str(int(t)) for t in ticks])
                axes.minorticks_off()
            axes.set_xlabel(xlabel)
            axes.set_ylabel(f"{metric.split('_')[0]} RMSE (m)")
            axes.set_title(f"{metric.split('_')[0]} RMSE, {fixed}, σ = {sigma:g} m (▲ off scale)",
                           fontsize="small")
            axes.grid(alpha=0.3, which="major")
    grid[0, 0].legend(fontsize="x-small")
    return figure
