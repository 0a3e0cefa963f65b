"""Summary statistics over seeds (SPEC 8, SPEC 12 `summary.csv`)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from scipy.special import stdtrit

SUMMARY_COLUMNS = ["method", "metric", "mean", "median", "ci_low", "ci_high", "n"]


def mean_ci(values, level: float = 0.95) -> tuple[float, float, float]:
    """Mean and Student-t confidence interval of the mean.

    Parameters
    ----------
    values : array_like, shape (n,)
        Samples; NaNs are dropped.
    level : float
        Coverage of the interval (0.95 gives the 95% interval).

    Returns
    -------
    mean, ci_low, ci_high : float
        The interval is mean ± t_{(1+level)/2, n-1} · s / √n; NaN when fewer
        than two finite samples remain (no spread to estimate).
    """
    x = np.asarray(values, dtype=float)
    x = x[np.isfinite(x)]
    if x.size == 0:
        return float("nan"), float("nan"), float("nan")
    mean = float(x.mean())
    if x.size < 2:
        return mean, float("nan"), float("nan")
    half = float(stdtrit(x.size - 1, 0.5 + level / 2.0) * x.std(ddof=1) / np.sqrt(x.size))  # t quantile
    return mean, mean - half, mean + half


def summarise(metrics: pd.DataFrame, level: float = 0.95) -> pd.DataFrame:
    """One row per (method, numeric metric): mean, median, 95% interval, n.

    ``metrics`` has one row per seed and method (SPEC 12); the ``seed`` column
    and non-numeric columns are not summarised. Row order follows the first
    appearance of each method, then the column order of ``metrics``.
    """
    if "method" not in metrics.columns:
        raise ValueError("metrics table needs a 'method' column")
    numeric = [
        c for c in metrics.columns
        if c not in ("seed", "method") and pd.api.types.is_numeric_dtype(metrics[c])
        and not pd.api.types.is_bool_dtype(metrics[c])
    ]
    rows = []
    for method in pd.unique(metrics["method"]):
        block = metrics[metrics["method"] == method]
        for metric in numeric:
            column = block[metric].to_numpy(dtype=float)
            finite = column[np.isfinite(column)]
            if finite.size == 0:
                continue
            mean, low, high = mean_ci(finite, level)
            rows.append([method, metric, mean, float(np.median(finite)), low, high, int(finite.size)])
    return pd.DataFrame(rows, columns=SUMMARY_COLUMNS)
