"""LaTeX tables and number macros for the reproduction report (pure: tables in, text out).

The report's numbers come only from ``summary.csv`` of a results folder and
from ``paper/paper_numbers.csv`` (the article's own values, each with its
source). Everything here turns those tables into LaTeX text; the I/O lives in
``experiments/report.py``.

Macro scheme (defined with ``\\csname`` so keys may hold ``_`` and ``-``; the
report reads them through guards that print "n/a" when a key is missing):

- ``val@<key>@<method>@<metric>@<stat>``: a summary value, stat one of mean,
  median, ci_low, ci_high, n (``\\val`` in ``report.tex``);
- ``paper@<experiment>@<method>@<metric>``: the article's value (``\\paperval``);
- ``best@<key>@<metric>``: the method with the best mean (``\\best``);
- ``src@<key>``: results folder, git sha and seed count (``\\srcof``);
- ``srcname@<key>``: the results folder alone, ``<experiment>/<folder>`` (``\\srcname``);
- ``papersrc@<key>@<table>``: which table of the article a table's "paper"
  column comes from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import pandas as pd

from stslam.slam.decision_scores import judged_rows

METHOD_LABELS = {
    "odometry": "Odometry only",
    "ekf_slam": "EKF SLAM",
    "dyn_slam": "Dyn.\\ SLAM",
    "ekf_slam_gated": "Gated EKF SLAM",
    "a_slam": "A-SLAM",
    "a_slam_truth_onsets": "A-SLAM, onsets from truth",
    "oracle": "Oracle A-SLAM",
    "joint": "Joint",
    "separate": "Separate",
    "crb": "Cram\\'er--Rao bound",
    "static": "Static point",
    "prismatic": "Prismatic point",
    "revolute": "Revolute point",
    "imm": "IMM selector",
}

METRIC_LABELS = {
    "ate_m": "ATE (m)",
    "rpe_m": "RPE (m)",
    "nees": "mean NEES",
    "nees_in_band": "in 95\\% band",
    "nees_frac_out": "frames $>\\chi^2_{3,0.999}$",
    "diverged": "diverged",
    "centre_error": "centre error (m)",
    "radius_error": "radius error (m)",
    "centre_rmse": "centre RMSE (m)",
    "radius_rmse": "radius RMSE (m)",
    "filtered_rmse": "filtered RMSE (rad)",
    "pred1_rmse": "1-step RMSE (rad)",
    "predk_rmse": "$k$-step RMSE (rad)",
    "loglik": "log-likelihood",
    "selection_step": "selection step",
    "wrong_argmax_step": "arg-max wrong at",
    "correct": "correct",
    "decision_delay_s": "decided after onset (s)",
    "selection_time_s": "decision time (s)",
    "fit_residual_m": "fit residual (m)",
    "radius_error_m": "radius error (m)",
    "axis_angle_deg": "axis angle (deg)",
    "axis_dist_m": "axis distance (m)",
    "axis_angle_deg_true_poses": "axis angle, true poses (deg)",
    "axis_dist_m_true_poses": "axis dist., true poses (m)",
    "n_revolute": "revolute tracks",
}

# Metrics where a larger mean is better (for the ``best@`` macros); all others: smaller is better.
HIGHER_IS_BETTER = {"loglik", "correct", "nees_in_band", "moving_correct_frac", "static_correct_frac"}

_SPECIAL = {"&": "\\&", "%": "\\%", "$": "\\$", "#": "\\#", "_": "\\_", "{": "\\{", "}": "\\}",
            "~": "\\textasciitilde{}", "^": "\\textasciicircum{}", "\\": "\\textbackslash{}"}


@dataclass(frozen=True)
class TableSpec:
    """One table of an experiment: its name (file ``<key>/<name>.tex``), rows and columns.

    ``methods`` None: every method of the summary, in its order; ``paper``: whether
    the article's values (``paper_numbers.csv``) get a column beside ours.
    """

    name: str
    methods: tuple[str, ...] | None
    metrics: tuple[str, ...]
    paper: bool = True


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


def paper_number(value) -> str:
    """The article's number as ``paper_numbers.csv`` writes it (read as text: "0.60" stays "0.60")."""
    return latex_escape(str(value).strip())


def method_label(method: str) -> str:
    if method.startswith("order") and method[5:].isdigit():
        return f"Order {method[5:]}"
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
        Rows of ``paper_numbers.csv`` for this experiment (method, metric, value as text);
        a metric gets a "paper" column when it has at least one of them.
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
    rules = []
    for metric in present_metrics:
        span = 2 if metric in paper_metrics else 1
        first = len(head_sub) + 1
        head_top.append(f"\\multicolumn{{{span}}}{{c}}{{{metric_label(metric)}}}")
        head_sub.extend(["ours [95\\% CI]", "paper"][:span])
        rules.append(f"\\cmidrule(lr){{{first}-{first + span - 1}}}")
    lines = [f"\\begin{{tabular}}{{{spec}}}", "\\toprule", " & ".join(head_top) + " \\\\",
             "".join(rules), " & ".join(head_sub) + " \\\\", "\\midrule"]
    for method in present_methods:
        cells = [method_label(method)]
        for metric, kind in columns:
            if kind == "ours":
                match = summary[(summary["method"] == method) & (summary["metric"] == metric)]
                cells.append(_cell(None if match.empty else match.iloc[0], digits))
            else:
                match = paper[(paper["method"] == method) & (paper["metric"] == metric)]
                cells.append("--" if match.empty else paper_number(match.iloc[0]["value"]))
        lines.append(" & ".join(cells) + " \\\\")
    lines += ["\\bottomrule", "\\end{tabular}"]
    return "\n".join(lines) + "\n"


def _define(name: str, body: str) -> str:
    return f"\\expandafter\\def\\csname {name}\\endcsname{{{body}}}\n"


def value_macros(key: str, summary: pd.DataFrame, digits: int = 3) -> str:
    """Definitions of ``val@<key>@<method>@<metric>@<stat>`` for every summary value.

    ``\\val{<key>}{<method>}{<metric>}{<stat>}`` in the report expands to the
    number formatted as in the tables, e.g. ``\\val{dynamic_slam-square_centred}{a_slam}{ate_m}{mean}``.
    """
    out = []
    for _, row in summary.iterrows():
        for stat in ("mean", "median", "ci_low", "ci_high", "n"):
            value = row[stat]
            if stat.startswith("ci_") and math.isnan(float(value)):
                continue  # one seed: no interval, and \\meanci then prints the mean alone
            text = str(int(value)) if stat == "n" else format_number(value, digits)
            out.append(_define(f"val@{key}@{row['method']}@{row['metric']}@{stat}", text))
    return "".join(out)


def best_macros(key: str, summary: pd.DataFrame, methods: list[str], metrics: list[str]) -> str:
    """``best@<key>@<metric>``: the label of the method among ``methods`` with the best mean.

    Best is the largest mean for :data:`HIGHER_IS_BETTER` metrics and the smallest
    otherwise; metrics with no finite mean get no macro (the report prints n/a).
    """
    out = []
    for metric in metrics:
        rows = summary[(summary["metric"] == metric) & summary["method"].isin(methods)].dropna(subset=["mean"])
        if rows.empty:
            continue
        pick = rows["mean"].idxmax() if metric in HIGHER_IS_BETTER else rows["mean"].idxmin()
        out.append(_define(f"best@{key}@{metric}", method_label(str(rows.loc[pick, "method"]))))
    return "".join(out)


def paper_macros(paper_numbers: pd.DataFrame) -> str:
    """``paper@<experiment>@<method>@<metric>`` for every row of ``paper_numbers.csv`` (value as written)."""
    return "".join(_define(f"paper@{row['experiment']}@{row['method']}@{row['metric']}",
                           paper_number(row["value"]))
                   for _, row in paper_numbers.iterrows())


def paper_source_note(paper: pd.DataFrame | None, metrics: list[str]) -> str:
    """Caption text naming the article's tables a "paper" column was taken from ('' if none).

    The source column of ``paper_numbers.csv`` starts with the table's name
    ("Table II, row A-SLAM"); the part before the first comma is quoted.
    """
    if paper is None:
        return ""
    used = paper[paper["metric"].isin(metrics)]
    tables = list(dict.fromkeys(str(s).split(",")[0].strip() for s in used["source"]))
    if not tables:
        return ""
    return f"``paper'': the article's {' and '.join(latex_escape(t) for t in tables)}."


def source_text(folder_parts: list[str], git_sha: str, dirty: bool, n_seeds: int) -> str:
    """Caption text naming a results folder (path parts, last = folder name), git sha and seeds.

    Each path part is kept whole in an ``\\mbox`` with a break allowed after its
    slash, so long paths wrap between parts and the folder name is never split.
    """
    path = "\\allowbreak ".join(f"\\mbox{{\\texttt{{{latex_escape(part)}/}}}}" for part in folder_parts[:-1])
    path += f"\\allowbreak \\mbox{{\\texttt{{{latex_escape(folder_parts[-1])}}}}}"
    state = ", uncommitted changes" if dirty else ""
    seeds = "seed" if n_seeds == 1 else "seeds"
    return f"Source: {path} (git \\texttt{{{latex_escape(git_sha)}}}{state}; {n_seeds} {seeds})."


def source_macro(key: str, text: str) -> str:
    return _define(f"src@{key}", text)


def folder_name_macro(key: str, experiment_dir: str, folder: str) -> str:
    """``srcname@<key>``: ``<experiment dir>/<folder>`` in typewriter, the folder name kept whole."""
    return _define(f"srcname@{key}", f"\\mbox{{\\texttt{{{latex_escape(experiment_dir)}/}}}}\\allowbreak "
                                     f"\\mbox{{\\texttt{{{latex_escape(folder)}}}}}")


def paper_source_macro(key: str, table: str, text: str) -> str:
    return _define(f"papersrc@{key}@{table}", text)


def available_macro(key: str) -> str:
    return _define(f"have@{key}", "1")


def confusion_table(decisions: pd.DataFrame) -> str:
    """LaTeX tabular of A-SLAM's final model per true model, summed over seeds (``decisions.csv``,
    :func:`stslam.slam.decision_scores.decision_rows`): the movers seen moving and the static points."""
    seen = judged_rows(decisions)
    finals = [m for m in ("static", "prismatic", "revolute", "undecided") if m in set(seen["final_model"])]
    lines = ["\\begin{tabular}{l" + "r" * len(finals) + "r}", "\\toprule",
             "true $\\backslash$ final & " + " & ".join(finals) + " & right \\\\", "\\midrule"]
    for true in ("static", "prismatic", "revolute"):
        rows = seen[seen["true_model"] == true]
        if not len(rows):
            continue
        counts = [int((rows["final_model"] == m).sum()) for m in finals]
        lines.append(f"{true} & " + " & ".join(str(c) for c in counts)
                     + f" & {format_number(float((rows['final_model'] == true).mean()), 3)} \\\\")
    lines += ["\\bottomrule", "\\end{tabular}", ""]
    return "\n".join(lines)
