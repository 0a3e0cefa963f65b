"""LaTeX tables and number macros for the reproduction report (pure: tables in, text out).

The report's numbers come only from ``summary.csv`` / ``metrics.csv`` of a
results folder and from ``paper/paper_numbers.csv`` (the paper's own values).
"""

from __future__ import annotations

import math

import pandas as pd

METHOD_LABELS = {
    "ekf_slam": "EKF SLAM",
    "dyn_slam": "Dyn.\\ SLAM",
    "ekf_slam_gated": "Gated EKF SLAM",
    "a_slam": "A-SLAM",
    "oracle": "Oracle A-SLAM",
    "joint": "Joint",
    "separate": "Separate",
    "crb": "Cram\\'er--Rao bound",
}

METRIC_LABELS = {
    "ate_m": "ATE (m)",
    "rpe_m": "RPE (m)",
    "nees": "NEES",
    "centre_error": "centre error",
    "radius_error": "radius error",
    "centre_rmse": "centre RMSE",
    "radius_rmse": "radius RMSE",
    "filtered_rmse": "filtered RMSE",
    "pred1_rmse": "1-step RMSE",
    "predk_rmse": "$k$-step RMSE",
    "loglik": "log-lik.",
    "selection_step": "selection step",
    "correct": "correct",
    "axis_angle_deg": "axis angle (deg)",
    "axis_dist_m": "axis dist.\\ (m)",
}

_SPECIAL = {"&": "\\&", "%": "\\%", "$": "\\$", "#": "\\#", "_": "\\_", "{": "\\{", "}": "\\}",
            "~": "\\textasciitilde{}", "^": "\\textasciicircum{}", "\\": "\\textbackslash{}"}


def latex_escape(text: str) -> str:
    """Escape LaTeX's special characters in plain text."""
    return "".join(_SPECIAL.get(ch, ch) for ch in str(text))


def format_number(value: float, digits: int = 3) -> str:
    """``digits`` significant figures, fixed-point (no exponent) for |x| ≥ 1e-4.

    The same function formats the numbers the report prints and the strings a
    test searches for in the PDF text, so the two cannot drift apart.
    """
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "--"
    value = float(value)
    if value == 0.0:
        return "0"
    magnitude = math.floor(math.log10(abs(value)))
    if magnitude < -4:
        return f"{value:.{digits - 1}e}"
    decimals = max(digits - 1 - magnitude, 0)
    return f"{value:.{decimals}f}"


def method_label(method: str) -> str:
    return METHOD_LABELS.get(method, latex_escape(method))


def metric_label(metric: str) -> str:
    return METRIC_LABELS.get(metric, latex_escape(metric))


def _cell(row: pd.Series | None, digits: int) -> str:
    if row is None:
        return "--"
    text = format_number(row["mean"], digits)
    if not (math.isnan(row["ci_low"]) or math.isnan(row["ci_high"])):
        text += (f" {{\\scriptsize[{format_number(row['ci_low'], digits)},"
                 f" {format_number(row['ci_high'], digits)}]}}")
    return text


def comparison_table(summary: pd.DataFrame, methods: list[str], metrics: list[str],
                     paper: pd.DataFrame | None = None, digits: int = 3) -> str:
    """A booktabs ``tabular``: rows = methods, per metric our mean [95% CI] and the paper's value.

    Parameters
    ----------
    summary : DataFrame
        ``summary.csv`` of one run (columns method, metric, mean, median, ci_low, ci_high, n).
    methods, metrics : list of str
        Rows and metric columns, in order; methods or metrics absent from
        ``summary`` are skipped.
    paper : DataFrame, optional
        Rows of ``paper_numbers.csv`` for this experiment (method, metric, value).
    """
    present_methods = [m for m in methods if (summary["method"] == m).any()]
    present_metrics = [m for m in metrics if (summary["metric"] == m).any()]
    paper_metrics = set() if paper is None else set(paper["metric"])
    columns = []
    for metric in present_metrics:
        columns.append((metric, "ours"))
        if metric in paper_metrics:
            columns.append((metric, "paper"))
    spec = "l" + "r" * len(columns)
    head_top = ["Method"]
    head_sub = [""]
    for metric in present_metrics:
        span = 2 if metric in paper_metrics else 1
        head_top.append(f"\\multicolumn{{{span}}}{{c}}{{{metric_label(metric)}}}")
        head_sub.extend(["ours [95\\% CI]", "paper"][:span])
    lines = [f"\\begin{{tabular}}{{{spec}}}", "\\toprule", " & ".join(head_top) + " \\\\",
             " & ".join(head_sub) + " \\\\", "\\midrule"]
    for method in present_methods:
        cells = [method_label(method)]
        for metric, kind in columns:
            if kind == "ours":
                match = summary[(summary["method"] == method) & (summary["metric"] == metric)]
                cells.append(_cell(None if match.empty else match.iloc[0], digits))
            else:
                match = paper[(paper["method"] == method) & (paper["metric"] == metric)]
                cells.append("--" if match.empty else format_number(match.iloc[0]["value"], digits))
        lines.append(" & ".join(cells) + " \\\\")
    lines += ["\\bottomrule", "\\end{tabular}"]
    return "\n".join(lines) + "\n"


def value_macros(experiment: str, summary: pd.DataFrame, digits: int = 3, variant: str = "") -> str:
    """``\\csname`` definitions so the report text can cite any summary value.

    ``\\val{<experiment>}{<method>}{<metric>}{<stat>}`` expands to the number,
    e.g. ``\\val{dynamic_slam}{a_slam}{ate_m}{mean}``; stats are mean, median,
    ci_low, ci_high and n. ``variant`` (e.g. a world name) is appended to the
    experiment name as ``<experiment>/<variant>``.
    """
    key = experiment if not variant else f"{experiment}/{variant}"
    out = []
    for _, row in summary.iterrows():
        for stat in ("mean", "median", "ci_low", "ci_high", "n"):
            value = row[stat]
            text = str(int(value)) if stat == "n" else format_number(value, digits)
            out.append(f"\\expandafter\\def\\csname val@{key}@{row['method']}@{row['metric']}@{stat}"
                       f"\\endcsname{{{text}}}")
    return "\n".join(out) + "\n"
