"""Figures of the speed benchmark."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure


SELECTION_FREE = "the same, were A-SLAM's selection free (s; estimate)"


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


def benchmark_table(step_times: dict, ratios: dict, metrics, n_seeds: int, repeats: int,
                    floor_ratios: dict | None = None) -> list[str]:
    """The benchmark as Markdown lines (the README's benchmark section): per-step times per world and
    filter (ms, median over seeds), the A-SLAM / EKF SLAM ratio (and, given ``floor_ratios``, that of
    A-SLAM without its selection), and the single-number metrics of ``metrics`` (a metrics.csv frame)
    with their targets (SPEC 11, 16)."""
    worlds = list(step_times)
    methods = list(dict.fromkeys(m for w in worlds for m in step_times[w].index))
    lines = [f"Per-step CPU time (ms; median of {n_seeds} seeds, fastest of {repeats} runs, filters side by side):",
             "", "| filter | " + " | ".join(worlds) + " |", "|---" * (len(worlds) + 1) + "|"]
    for method in methods:
        cells = [f"{1e3 * step_times[w][method]:.3f}" if method in step_times[w].index else "–" for w in worlds]
        lines.append(f"| {method} | " + " | ".join(cells) + " |")
    lines.append("| **a_slam / ekf_slam** (≤ 1.5) | " + " | ".join(
        f"**{ratios[w]:.2f}**" if w in ratios else "–" for w in worlds) + " |")
    if floor_ratios:
        lines.append("| a_slam_no_selection / ekf_slam | " + " | ".join(
            f"{floor_ratios[w]:.2f}" if w in floor_ratios else "–" for w in worlds) + " |")
    single = [("seed_time_s", "all_filters", "one `dynamic_slam` seed, all five filters (s)", "< 1", "{:.2f}"),
              ("seed_time_s", "all_filters_no_selection", SELECTION_FREE, "", "{:.2f}"),
              ("seed_time_s", "all_filters@isam2", "the same under `backend=isam2` (s)", "≤ 10", "{:.2f}"),
              ("seed_time_s", "all_filters@kitchen@isam2", "one kitchen seed under `backend=isam2`, all five (s)",
               "≤ 30", "{:.2f}"),
              ("pipeline_fps", "fridge_pipeline", "fridge pipeline, 640×480, one core (frames/s)", "≥ 30", "{:.1f}"),
              ("frontend_fps", "frontend", "fridge front end alone, 640×480 (frames/s)", "≥ 30", "{:.1f}"),
              ("selection_obs_per_s", "selection", "online selection (observations/s)", "≥ 10,000", "{:,.0f}"),
              ("scaling_slope", "ekf_core", "per-step cost against landmarks, log–log slope to 1,000", "≤ 2",
               "{:.2f}"),
              ("kernel_warmup_s", "kernels", "compiled kernels' first calls (s; compiled once per checkout)", "",
               "{:.2f}"),
              ("kernel_warmup_peak_rss_mb", "kernels", "peak memory of the process that made those calls (MB)", "",
               "{:.0f}"),
              ("peak_rss_mb", "process", "peak memory (MB)", "", "{:.0f}")]
    lines += ["", "| measure | value | target |", "|---|---|---|"]
    for metric, method, label, target, form in single:
        if metric in metrics:
            values = metrics.loc[metrics["method"] == method, metric].dropna()
            if values.size:
                lines.append(f"| {label} | {form.format(float(np.median(values)))} | {target} |")
    return lines


# (metric, method, label, format, target as ours / baseline or None): the measures compared with another
# commit's benchmark run beside this one (SPEC 18: ratios measured side by side, since the machine's speed varies)
COMPARED = (("selection_obs_per_s", "selection", "online selection (observations/s)", "{:,.0f}", "≥ 2"),
            ("seed_time_s", "all_filters", "one `dynamic_slam` seed, all five filters (s)", "{:.2f}", "≤ 0.6"),
            ("seed_time_s", "all_filters_no_selection", SELECTION_FREE, "{:.2f}", None),
            ("pipeline_fps", "fridge_pipeline", "fridge pipeline, 640×480, one core (frames/s)", "{:.1f}", "≥ 1.5"),
            ("frontend_fps", "frontend", "fridge front end alone, 640×480 (frames/s)", "{:.1f}", None),
            ("step_time_s_paper_square", "a_slam", "A-SLAM per step, paper_square (ms)", "ms", None),
            ("step_time_s_square_centred", "a_slam", "A-SLAM per step, square_centred (ms)", "ms", None),
            ("step_time_s_kitchen", "a_slam", "A-SLAM per step, kitchen (ms)", "ms", None),
            ("step_time_ratio_paper_square", "a_slam/ekf_slam", "A-SLAM / EKF SLAM per step, paper_square",
             "{:.2f}", None),
            ("step_time_ratio_square_centred", "a_slam/ekf_slam", "A-SLAM / EKF SLAM per step, square_centred",
             "{:.2f}", None),
            ("step_time_ratio_kitchen", "a_slam/ekf_slam", "A-SLAM / EKF SLAM per step, kitchen", "{:.2f}", None),
            ("scaling_slope", "ekf_core", "per-step cost against landmarks, log–log slope to 1,000", "{:.2f}", None),
            ("peak_rss_mb", "process", "peak memory (MB)", "{:.0f}", None))


# A measure compared with another method's of the baseline run: the seed with A-SLAM's selection free against
# the baseline's whole seed (what the seed's ratio would be were selection free; experiments/bench.py)
BASELINE_METHOD = {"all_filters_no_selection": "all_filters"}


def _median(metrics, metric: str, method: str) -> float | None:
    if metric not in metrics:
        return None
    values = metrics.loc[metrics["method"] == method, metric].dropna()
    return float(np.median(values)) if values.size else None


def comparison_table(ours, baseline, ours_label: str, baseline_label: str) -> list[str]:
    """Markdown lines: each measure of :data:`COMPARED` in two metrics.csv frames side by side (medians over
    seeds), with their ratio ours / baseline and, where SPEC 18 sets one, the target on that ratio."""
    lines = [f"| measure | {ours_label} | {baseline_label} | ratio | target |", "|---|---|---|---|---|"]
    for metric, method, label, form, target in COMPARED:
        mine, theirs = _median(ours, metric, method), _median(baseline, metric, BASELINE_METHOD.get(method, method))
        if mine is None and (theirs is None or method in BASELINE_METHOD):
            continue  # (measured in neither run, or one read from another of the baseline's measures)

        def cell(value, form=form):
            if value is None:
                return "–"
            return f"{1e3 * value:.3f}" if form == "ms" else form.format(value)

        ratio = f"{mine / theirs:.2f}" if mine is not None and theirs else "–"
        lines.append(f"| {label} | {cell(mine)} | {cell(theirs)} | {ratio} | {target or ''} |")
    return lines
