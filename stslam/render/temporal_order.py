"""Figures of the temporal-order experiment (SPEC 8.2, paper §VII-B)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure


def filtered_trace_figure(times, observed, truth, filtered, filtered_std, start: int, orders,
                          title: str = "") -> Figure:
    """Data and the filtered angle of each order, one panel per order (like the paper's figure).

    Parameters
    ----------
    times : numpy.ndarray, shape (n,)
        Sample times (s).
    observed : numpy.ndarray, shape (n,)
        Observed angles (rad).
    truth : numpy.ndarray, shape (n,) or None
        Noise-free angles (rad), when known.
    filtered, filtered_std : numpy.ndarray, shape (n_orders, n)
        Filtered angle q_{t|t} and its standard deviation √P₀₀ (rad); NaN
        before ``start``.
    start : int
        Index of the last initialisation sample (marked by a dotted line).
    orders : sequence of int
        Temporal order of each row.
    """
    figure = Figure(figsize=(6.4, 1.9 * len(orders) + 0.6), layout="constrained")
    axes_list = figure.subplots(len(orders), 1, sharex=True, squeeze=False)[:, 0]
    colours = [f"C{i}" for i in range(len(orders))]
    for axes, order, q, std, colour in zip(axes_list, orders, filtered, filtered_std, colours):
        axes.plot(times, observed, ".", color="0.45", markersize=4, label="observed")
        if truth is not None:
            axes.plot(times, truth, "-", color="black", linewidth=0.8, label="true")
        axes.plot(times, q, "-", color=colour, linewidth=1.6, label=f"filtered, order {order}")
        axes.fill_between(times, q - 2 * std, q + 2 * std, color=colour, alpha=0.2, linewidth=0,
                          label="±2σ")
        axes.axvline(times[start], color="0.6", linestyle=":", linewidth=1)
        axes.set_ylabel("angle (rad)")
        axes.legend(loc="upper right", fontsize=7, ncols=2)
    axes_list[-1].set_xlabel("time (s)")
    if title:
        figure.suptitle(title, fontsize=10)
    return figure


def horizon_figure(horizon_table: pd.DataFrame, reference: str) -> Figure:
    """Prediction RMSE against horizon, one line per order, with 95% intervals over seeds.

    Parameters
    ----------
    horizon_table : pandas.DataFrame
        Columns ``method, horizon, mean, ci_low, ci_high`` (RMSE in rad,
        horizon in samples); NaN intervals (a single trace) draw no band.
    reference : str
        What the predictions are compared with ("true angle" or "observations").
    """
    figure = Figure(figsize=(5.0, 3.4), layout="constrained")
    axes = figure.add_subplot()
    methods = list(pd.unique(horizon_table["method"]))
    for i, method in enumerate(methods):
        block = horizon_table[horizon_table["method"] == method].sort_values("horizon")
        h = block["horizon"].to_numpy(dtype=float)
        mean = block["mean"].to_numpy(dtype=float)
        low = block["ci_low"].to_numpy(dtype=float)
        high = block["ci_high"].to_numpy(dtype=float)
        axes.plot(h, mean, marker="o", color=f"C{i}", label=method)
        if np.any(np.isfinite(low)):
            axes.fill_between(h, low, high, color=f"C{i}", alpha=0.2, linewidth=0)
    axes.set_xlabel("prediction horizon (samples)")
    axes.set_ylabel(f"RMSE against {reference} (rad)")
    axes.set_ylim(bottom=0)
    axes.legend()
    return figure
