"""Figures of a merged sweep: a metric against a swept parameter, per method, with 95% intervals."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.figure import Figure


def metric_vs_parameter(summary: pd.DataFrame, key: str, metric: str) -> Figure:
    """Mean and 95% interval of ``metric`` against the swept ``key``, one line per method.

    Parameter values are plotted as numbers when they all parse as numbers,
    otherwise as categories in sweep order.
    """
    rows = summary[summary["metric"] == metric]
    figure = Figure(figsize=(5.0, 3.4), layout="constrained")
    axes = figure.add_subplot()
    values = pd.unique(rows[key])
    numeric = pd.to_numeric(pd.Series(values), errors="coerce")
    positions = dict(zip(values, numeric if numeric.notna().all() else np.arange(len(values))))
    for method, block in rows.groupby("method", sort=False):
        x = np.array([positions[v] for v in block[key]], dtype=float)
        order = np.argsort(x)
        mean = block["mean"].to_numpy()[order]
        low = block["ci_low"].to_numpy()[order]
        high = block["ci_high"].to_numpy()[order]
        axes.plot(x[order], mean, marker="o", label=method)
        axes.fill_between(x[order], low, high, alpha=0.2)
    if not numeric.notna().all():
        axes.set_xticks(list(positions.values()), [str(v) for v in positions])
    axes.set_xlabel(key)
    axes.set_ylabel(metric)
    axes.grid(alpha=0.3)
    axes.legend(fontsize="small")
    return figure
