"""The report's back-end comparison: one world's EKF run beside its iSAM2 run (SPEC 14).

Both runs' ``metrics.csv`` give the rows; every number is a mean over the seeds
the two runs share (the EKF run may have more), so the columns compare the
same simulated sequences, each with its 95% interval over those seeds (Student t, as the
report's other tables). Per method: the EKF's ATE, iSAM2's smoothed and causal ATE (``ate_m``,
``ate_online_m``), the smoothed ATE over the EKF's, and the robot NEES of
each (the EKF's, iSAM2's from the smoother's marginals, smoothed and causal).
Across methods (:func:`cross_macros`): one method's smoothed ATE against another's under the EKF,
in the mean and seed by seed (A-SLAM on iSAM2 against the gated EKF, SPEC 16).
"""

from __future__ import annotations

import math

import pandas as pd

from stslam.eval.stats import mean_ci
from stslam.render.report_tables import _define, format_number, method_label

COLUMNS = (  # (run, metric, header)
    ("ekf", "ate_m", "EKF"),
    ("isam2", "ate_m", "smoothed"),
    ("isam2", "ate_online_m", "causal"),
    ("ratio", "ate_m", "smoothed / EKF"),
    ("ekf", "nees", "EKF"),
    ("isam2", "nees", "smoothed"),
    ("isam2", "nees_online", "causal"),
)


def common_seeds(ekf: pd.DataFrame | None, isam2: pd.DataFrame) -> list:
    """Seeds present in both runs' ``metrics.csv``, sorted (the iSAM2 run's when there is no EKF run)."""
    return sorted(set(isam2["seed"]) if ekf is None else set(ekf["seed"]) & set(isam2["seed"]))


def _mean(metrics: pd.DataFrame | None, method: str, metric: str, seeds: list) -> float:
    if metrics is None or metric not in metrics:
        return math.nan
    rows = metrics[(metrics["method"] == method) & metrics["seed"].isin(seeds)]
    return float(rows[metric].mean()) if len(rows) else math.nan


def _cell(metrics: pd.DataFrame | None, method: str, metric: str, seeds: list, digits: int) -> str:
    """The mean over ``seeds`` with its 95% interval (the mean alone when there is no spread to estimate)."""
    if metrics is None or metric not in metrics:
        return format_number(math.nan, digits)
    rows = metrics[(metrics["method"] == method) & metrics["seed"].isin(seeds)]
    mean, low, high = mean_ci(rows[metric].to_numpy(dtype=float)) if len(rows) else (math.nan,) * 3
    text = format_number(mean, digits)
    if math.isfinite(low) and math.isfinite(high):
        text += f" {{\\scriptsize[{format_number(low, digits)}, {format_number(high, digits)}]}}"
    return text


def ate_ratio(ekf: pd.DataFrame, isam2: pd.DataFrame, method: str) -> float:
    """iSAM2's smoothed mean ATE over the EKF's for ``method`` on the common seeds (NaN when missing)."""
    seeds = common_seeds(ekf, isam2)
    return _mean(isam2, method, "ate_m", seeds) / _mean(ekf, method, "ate_m", seeds)


def backend_table(ekf: pd.DataFrame, isam2: pd.DataFrame, methods: list[str], digits: int = 3) -> str:
    """A booktabs ``tabular`` of :data:`COLUMNS` for the ``methods`` both runs have (means over the common seeds).

    ``ekf``, ``isam2``: the two runs' ``metrics.csv`` (columns seed, method and the metrics); ``ekf``
    None: no EKF run, its columns are empty.
    """
    seeds = common_seeds(ekf, isam2)
    present = [m for m in methods if (isam2["method"] == m).any() and (ekf is None or (ekf["method"] == m).any())]
    lines = ["\\begin{tabular}{lrrrrrrr}", "\\toprule",
             " & \\multicolumn{4}{c}{ATE (m)} & \\multicolumn{3}{c}{robot NEES} \\\\",
             "\\cmidrule(lr){2-5}\\cmidrule(lr){6-8}",
             "Method & " + " & ".join(header for _, _, header in COLUMNS) + " \\\\", "\\midrule"]
    for method in present:
        cells = [method_label(method)]
        for run, metric, _ in COLUMNS:
            if run == "ratio":
                cells.append(format_number(ate_ratio(ekf, isam2, method), digits))
            else:
                cells.append(_cell(ekf if run == "ekf" else isam2, method, metric, seeds, digits))
        lines.append(" & ".join(cells) + " \\\\")
    note = f"{len(seeds)} seeds common to both runs" if ekf is not None else f"{len(seeds)} seeds; no EKF run found"
    lines += ["\\midrule", f"\\multicolumn{{8}}{{l}}{{\\footnotesize {note}}} \\\\",
              "\\bottomrule", "\\end{tabular}"]
    return "\n".join(lines) + "\n"


def ratio_macros(key: str, ekf: pd.DataFrame | None, isam2: pd.DataFrame, methods: list[str], digits: int = 3) -> str:
    """``ratio@<key>@<method>``: :func:`ate_ratio` of the runs' ``metrics.csv`` formatted as in the table
    (``\\ateratio{key}{method}`` in the report)."""
    return "".join(_define(f"ratio@{key}@{m}", format_number(ate_ratio(ekf, isam2, m), digits)) for m in methods
                   if math.isfinite(ate_ratio(ekf, isam2, m)))


def _per_seed(metrics: pd.DataFrame, method: str, seeds: list) -> pd.Series:
    rows = metrics[(metrics["method"] == method) & metrics["seed"].isin(seeds)]
    return rows.set_index("seed")["ate_m"]


def cross_macros(key: str, ekf: pd.DataFrame | None, isam2: pd.DataFrame, methods: list[str], digits: int = 3) -> str:
    """``cross@<key>@<m>@<b>``: iSAM2's smoothed mean ATE of method m over the EKF's mean ATE of method b,
    and ``below@<key>@<m>@<b>``: on how many of the seeds both have m's smoothed ATE is below b's EKF ATE
    ("9 of 10"), on the seeds common to both runs (``\\crossratio`` and ``\\crossbelow`` in the report).
    Nothing without an EKF run. Given one EKF run as both, its own methods against each other."""
    if ekf is None:
        return ""
    seeds = common_seeds(ekf, isam2)
    out = []
    for m in methods:
        for b in methods:
            smoothed, baseline = _per_seed(isam2, m, seeds), _per_seed(ekf, b, seeds)
            both = smoothed.index.intersection(baseline.index)
            if len(both) == 0 or m == b:
                continue
            out.append(_define(f"cross@{key}@{m}@{b}", format_number(smoothed[both].mean() / baseline[both].mean(),
                                                                     digits)))
            out.append(_define(f"below@{key}@{m}@{b}", f"{int((smoothed[both] < baseline[both]).sum())} of {len(both)}"))
    return "".join(out)
