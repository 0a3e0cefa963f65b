"""Temporal order of a directly observed door angle (SPEC 8.2, paper §VII-B).

Kalman filters of orders k = 0, 1, 2, … (SPEC 3) run on generated
spring-loaded door traces (``n_seeds`` of them, seed k from ``seed + k``) or
once on a user's CSV trace (``trace.csv=<path>``). Per trace and order:

- ``filtered_rmse``: RMSE of the filtered angle q_{t|t},
- ``pred1_rmse``: RMSE of the one-step prediction q_{t|t−1},
- ``predk_rmse``: RMSE of the ``k_ahead``-step prediction q_{t|t−k},
- ``loglik``: Σ_t log N(y_t; 0, S_t) over the filtered samples,
- ``nis_mean``: mean normalised innovation squared (1 for a consistent filter),
- ``sigma_eta``, ``sigma_obs``: the maximum-likelihood noise levels (``filter=tuned`` only).

Errors are taken against the noise-free angle for generated traces and
against the observations for a user trace (its truth is unknown). Every score
covers the samples after the initialisation window (the same samples for every
order); a prediction h samples ahead is scored from window end + h on.
"""

from __future__ import annotations

from dataclasses import astuple, dataclass

import numpy as np
import pandas as pd

from stslam.config.kalman import trace_fit_from_config
from stslam.config.sim import door_scenario_from_config
from stslam.sim.door_trace import generate_trace
from stslam.errors import ConfigError
from stslam.output import ExperimentOutput
from stslam.config.readers import get_float, get_int, lookup, run_settings
from stslam.experiments.seeds import SeedRunner
from stslam.render.temporal_order import filtered_trace_figure, horizon_figure
from stslam.eval.stats import mean_ci
from stslam.kalman.trace_fit import fit_order
from stslam.io.trace_csv import read_angle_trace


@dataclass(frozen=True)
class _Trace:
    seed: int
    times: np.ndarray
    observed: np.ndarray
    truth: np.ndarray | None


def _orders(cfg) -> list[int]:
    value = lookup(cfg, "orders")
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) or not value:
        raise ConfigError(f"orders: expected a non-empty list of integers ≥ 0, got {value!r}")
    orders = []
    for i, item in enumerate(value):
        if isinstance(item, bool) or not isinstance(item, int) or item < 0:
            raise ConfigError(f"orders[{i}]: expected an integer ≥ 0, got {item!r}")
        if item in orders:
            raise ConfigError(f"orders[{i}]: order {item} is listed twice")
        orders.append(item)
    return orders


def _rmse(errors) -> float:
    errors = np.asarray(errors, dtype=float)
    errors = errors[np.isfinite(errors)]
    return float(np.sqrt(np.mean(errors**2))) if errors.size else float("nan")


def _horizon_summary(horizon_rows: pd.DataFrame) -> pd.DataFrame:
    rows = []
    for (method, horizon), block in horizon_rows.groupby(["method", "horizon"], sort=False):
        mean, low, high = mean_ci(block["rmse"])
        rows.append([method, horizon, mean, float(np.nanmedian(block["rmse"])), low, high,
                     int(np.isfinite(block["rmse"]).sum())])
    return pd.DataFrame(rows, columns=["method", "horizon", "mean", "median", "ci_low", "ci_high", "n"])


def _summary_lines(metrics: pd.DataFrame, header: str, columns) -> list[str]:
    lines = [header, f"{'method':8s}" + "".join(f"{c:>28s}" for c in columns)]
    for method, block in metrics.groupby("method", sort=False):
        cells = []
        for column in columns:
            mean, low, high = mean_ci(block[column])
            cells.append(f"{mean:.4g}" + (f" [{low:.4g}, {high:.4g}]" if np.isfinite(low) else ""))
        lines.append(f"{method:8s}" + "".join(f"{c:>28s}" for c in cells))
    return lines


def run(cfg: dict, seeds: SeedRunner | None = None) -> ExperimentOutput:
    """Run the temporal-order comparison described in the module docstring (SPEC 8.2); ``seeds`` runs
    the traces (:mod:`stslam.experiments.seeds`; None: one after another here)."""
    # Configuration first (SPEC 12): one line naming a bad parameter, before any work.
    seed, n_seeds, show_progress = astuple(run_settings(cfg))
    dt = get_float(cfg, "dt", low=0, low_open=True)
    orders = _orders(cfg)
    k_ahead = get_int(cfg, "k_ahead", low=1)
    horizon_max = get_int(cfg, "horizon_max", low=k_ahead)
    settings = trace_fit_from_config(cfg)
    if settings.window < max(orders) + 1:
        raise ConfigError(f"filter.window: expected ≥ {max(orders) + 1} samples to initialise order "
                          f"{max(orders)}, got {settings.window}")
    filter_name = str(lookup(cfg, "filter.name", "custom"))
    csv_path = lookup(cfg, "trace.csv", None)
    min_rows = settings.window + horizon_max
    if csv_path is None:
        scenario = door_scenario_from_config(cfg)
        if scenario.n_samples < min_rows:
            raise ConfigError(f"door.n_samples: expected ≥ filter.window + horizon_max = {min_rows}, "
                              f"got {scenario.n_samples}")
        plot_seed = get_int(cfg, "plot_seed", low=0, high=n_seeds - 1)
    else:
        if not isinstance(csv_path, str) or not csv_path:
            raise ConfigError(f"trace.csv: expected a file path or null, got {csv_path!r}")
        plot_seed = 0

    if csv_path is None:
        traces = []
        for k in range(n_seeds):
            trace = generate_trace(scenario, dt, np.random.default_rng(seed + k))
            traces.append(_Trace(seed + k, trace.times, trace.angles_observed, trace.angles_true))
        reference_name = "true angle"
    else:
        times, angles = read_angle_trace(csv_path, dt=dt, min_rows=min_rows)
        traces = [_Trace(seed, times, angles, None)]
        reference_name = "observations"

    def one_trace(index: int) -> tuple[list, list, dict]:
        """Trace ``index``'s metric and horizon rows, and its filter results if the figure shows it."""
        trace = traces[index]
        reference = trace.truth if trace.truth is not None else trace.observed
        metric_rows, horizon_rows, shown = [], [], {}
        for order in orders:
            fit = fit_order(trace.times, trace.observed, order, settings, horizon_max)
            result = fit.result
            after = slice(result.start + 1, None)  # samples that were filtered
            row = {
                "seed": trace.seed,
                "method": f"order{order}",
                "filtered_rmse": _rmse(result.states[after, 0] - reference[after]),
                "pred1_rmse": _rmse(result.predicted[after, 0] - reference[after]),
                "predk_rmse": _rmse(result.predicted[:, k_ahead - 1] - reference),
                "loglik": float(np.nansum(result.log_likelihood)),
                "nis_mean": float(np.nanmean(result.nis)),
            }
            if settings.tune:
                row["sigma_eta"], row["sigma_obs"] = fit.sigma_eta, fit.sigma_obs
            metric_rows.append(row)
            for h in range(1, horizon_max + 1):
                horizon_rows.append({"seed": trace.seed, "method": f"order{order}", "horizon": h,
                                     "rmse": _rmse(result.predicted[:, h - 1] - reference)})
            if index == plot_seed:
                shown[order] = result
        return metric_rows, horizon_rows, shown

    metric_rows, horizon_rows, plotted = [], [], {}
    for index, (rows, horizons, shown) in enumerate(
            (seeds or SeedRunner()).map(one_trace, len(traces), "temporal_order", show_progress)):
        metric_rows.extend(rows)
        horizon_rows.extend(horizons)
        if index == plot_seed:
            plotted = shown

    metrics = pd.DataFrame(metric_rows)
    horizon_table = pd.DataFrame(horizon_rows)
    horizon_summary = _horizon_summary(horizon_table)

    shown = traces[plot_seed]
    start = plotted[orders[0]].start
    trace_figure = filtered_trace_figure(
        shown.times, shown.observed, shown.truth,
        np.array([plotted[o].states[:, 0] for o in orders]),
        np.sqrt(np.array([plotted[o].variances[:, 0] for o in orders])),
        start, orders,
        title=f"{'user trace' if csv_path else f'door trace, seed {shown.seed}'}, filter {filter_name}")
    figures = {"filtered_trace": trace_figure,
               "prediction_horizon": horizon_figure(horizon_summary, reference_name)}

    source = (f"user trace {csv_path} ({len(shown.times)} samples; n_seeds ignored)" if csv_path
              else f"{n_seeds} generated door traces")
    header = (f"temporal_order: {source}, filter={filter_name}; RMSE (rad) against the {reference_name}, "
              f"predk = {k_ahead} samples ahead; mean [95% CI]")
    columns = ["filtered_rmse", "pred1_rmse", "predk_rmse", "loglik"]
    lines = _summary_lines(metrics, header, columns)
    means = metrics.groupby("method", sort=False)["loglik"].mean()
    lines.append(f"highest mean innovation log-likelihood: {means.idxmax()}")
    return ExperimentOutput(
        metrics=metrics,
        figures=figures,
        tables={"prediction_horizon": horizon_table, "prediction_horizon_summary": horizon_summary},
        lines=lines,
    )
