"""Structure fit: joint vs separate circle estimation, with the Cramér–Rao bound (paper §VII-A, Table I; SPEC 8.1).

A 2D point on the circle of centre (2, 2) m and radius 1 m is observed with
N(0, σ²) noise on x and y (σ = 0.1 m). Methods (SPEC 12 names):

* ``joint`` — nonlinear least squares of z_t = c + r[cos(θ0 + ωt), sin(θ0 + ωt)]
  over (c, r, θ0, ω) (:func:`stslam.articulation.circle_fit.fit_circle_constant_rate`);
* ``separate`` — the circle fit alone, Taubin + geometric least squares
  (:func:`stslam.articulation.circle_fit.fit_circle`, SPEC 2.3);
* ``crb`` — the Cramér–Rao bound with the sample angles as nuisance parameters
  (:func:`stslam.articulation.crb.crb_circle_nuisance_angles`), the bound that applies
  to ``separate``; in the fair protocol also ``crb_joint``, the bound of the
  correctly specified constant-rate model (never above ``crb``).

Protocols (config ``protocol``):

* ``paper`` — the authors' setting (SPEC 8.1): 7 samples at 1.5π·[0.1, 1/6, 0.25,
  0.5, 0.6, 0.7, 0.9]; ``joint`` uses only the first 4 with time = sample index
  (a misspecified constant-rate model), ``separate`` all 7;
* ``fair`` — both methods on the same ``n_samples`` evenly timed samples at
  ``start_deg + arc_deg·i/(n−1)``, time = sample index.

Per seed k (noise from ``default_rng(seed + k)``) and method, ``metrics.csv``
holds ``centre_error`` = ‖ĉ − c‖ (m) and ``radius_error`` = |r̂ − r| (m); the
summary's mean of ``centre_error`` is the paper's Table I number. The RMSE over
seeds, ``centre_rmse`` = √(mean_k ‖ĉ_k − c‖²) and ``radius_rmse``, is not a mean
of per-seed values: it is added to ``summary.csv`` as its own rows (mean = the
RMSE, 95% interval = square root of the t-interval of the mean squared error,
median = root of the median squared error) and to the table ``rmse.csv``. For
``crb`` rows the per-seed values are those of an efficient estimator (errors
~ N(0, CRB)): ``centre_error`` = E‖e‖, ``radius_error`` = E|e|, and its RMSE rows
are the bound itself, √tr CRB_c and √CRB_rr. SPEC 11's target is
``separate centre_rmse ≤ 1.25 × crb centre_rmse`` where the arc is ≥ 90°.

A sweep over arc length and sample count (fair protocol, ``sweep.n_seeds``
runs per grid point; the arc sweep at ``n_samples``, the count sweep at
``arc_deg``) is written as ``sweep.csv`` and a figure.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import pandas as pd

from stslam.articulation.crb import (crb_circle_constant_rate, crb_circle_nuisance_angles,
                               expected_abs_gaussian, expected_norm_gaussian_2d)
from stslam.articulation.circle_fit import fit_circle, fit_circle_constant_rate
from stslam.errors import ConfigError, DegenerateFitError
from stslam.experiments.seeds import SeedRunner
from stslam.output import ExperimentOutput
from stslam.config.readers import get_bool, get_choice, get_float, get_float_list, get_int, lookup
from stslam.progress import progress
from stslam.render.structure_fit import single_run_figure, sweep_figure
from stslam.eval.stats import SUMMARY_COLUMNS, mean_ci, summarise

# SPEC 8.1: the authors' sample angles (fractions of 1.5π) and the joint fit's window.
PAPER_ANGLE_FRACTIONS = (0.1, 1.0 / 6.0, 0.25, 0.5, 0.6, 0.7, 0.9)
PAPER_JOINT_SAMPLES = 4
# SPEC 8.1: Table I, corrected reading (the paper printed this vector row by row).
PAPER_TABLE_I = {("joint", "centre_error"): 0.71, ("joint", "radius_error"): 0.60,
                 ("separate", "centre_error"): 0.085, ("separate", "radius_error"): 0.039}
CRB_TARGET_RATIO = 1.25  # SPEC 11
# Monte Carlo runs per unit of work (stslam.experiments.seeds): a run takes ~0.5 ms, so a unit of one
# would spend more on its checkpoint and worker than on the fits; 1000 make ~0.5 s.
SEED_BLOCK = 1000


@dataclass(frozen=True)
class Settings:
    """Validated configuration of one run."""

    seed: int
    n_seeds: int
    protocol: str
    arc_deg: float
    n_samples: int
    start_deg: float
    noise_sigma: float
    centre: np.ndarray
    radius: float
    sweep_n_seeds: int
    sweep_arcs_deg: tuple[float, ...]
    sweep_n_samples: tuple[int, ...]
    progress: bool


@dataclass(frozen=True)
class Protocol:
    """Which samples exist and which each method sees.

    angles_rad (n,) true angles about the centre; separate_idx, joint_idx index
    arrays into them; joint_times (len(joint_idx),) the times the joint model is
    given; joint_specified: whether the constant-rate model holds for them.
    """

    angles_rad: np.ndarray
    separate_idx: np.ndarray
    joint_idx: np.ndarray
    joint_times: np.ndarray
    joint_specified: bool


def _arc(cfg, key) -> float:
    return get_float(cfg, key, low=0.0, high=360.0, low_open=True)


def _check_distinct_angles(arc_deg: float, n_samples: int, key: str) -> None:
    """A 360° arc repeats its first angle at the end: it needs ≥ 4 samples for 3 distinct angles."""
    distinct = n_samples - 1 if arc_deg >= 360.0 else n_samples
    if distinct < 3:
        raise ConfigError(f"{key}: {n_samples} samples over {arc_deg:g}° give {distinct} distinct angles; "
                          "expected at least 3 (use n_samples ≥ 4 for a full circle)")


def read_settings(cfg: dict) -> Settings:
    """Check every value this experiment reads; ConfigError names the first bad one."""
    arcs = get_float_list(cfg, "sweep.arcs_deg")
    for i, arc in enumerate(arcs):
        if not 0.0 < arc <= 360.0:
            raise ConfigError(f"sweep.arcs_deg[{i}]: expected a number > 0 and ≤ 360, got {arc!r}")
    counts = lookup(cfg, "sweep.n_samples")
    if not isinstance(counts, (list, tuple)):
        raise ConfigError(f"sweep.n_samples: expected a list of integers, got {counts!r}")
    for i, count in enumerate(counts):
        if isinstance(count, bool) or not isinstance(count, int) or count < 3:
            raise ConfigError(f"sweep.n_samples[{i}]: expected an integer ≥ 3, got {count!r}")
    settings = Settings(
        seed=get_int(cfg, "seed", low=0),
        n_seeds=get_int(cfg, "n_seeds", low=1),
        protocol=get_choice(cfg, "protocol", ("paper", "fair")),
        arc_deg=_arc(cfg, "arc_deg"),
        n_samples=get_int(cfg, "n_samples", low=3),
        start_deg=get_float(cfg, "start_deg"),
        noise_sigma=get_float(cfg, "noise_sigma", low=0.0, low_open=True),
        centre=np.array(get_float_list(cfg, "centre", length=2)),
        radius=get_float(cfg, "radius", low=0.0, low_open=True),
        sweep_n_seeds=get_int(cfg, "sweep.n_seeds", low=0),
        sweep_arcs_deg=tuple(arcs),
        sweep_n_samples=tuple(int(c) for c in counts),
        progress=get_bool(cfg, "progress", default=False),
    )
    if settings.protocol == "fair":
        _check_distinct_angles(settings.arc_deg, settings.n_samples, "n_samples")
    if settings.sweep_n_seeds > 0:
        for arc in settings.sweep_arcs_deg:
            _check_distinct_angles(arc, settings.n_samples, "sweep.arcs_deg")
        for count in settings.sweep_n_samples:
            _check_distinct_angles(settings.arc_deg, count, "sweep.n_samples")
    return settings


def paper_protocol() -> Protocol:
    """SPEC 8.1 facts: 7 uneven angles; joint on the first 4 with time = index."""
    angles = 1.5 * np.pi * np.array(PAPER_ANGLE_FRACTIONS)
    joint = np.arange(PAPER_JOINT_SAMPLES)
    return Protocol(angles, np.arange(angles.size), joint, joint.astype(float), joint_specified=False)


def fair_protocol(arc_deg: float, n_samples: int, start_deg: float = 0.0) -> Protocol:
    """Both methods on n evenly timed samples at start + arc·i/(n−1) (degrees), time = index."""
    idx = np.arange(n_samples)
    angles = np.radians(start_deg + arc_deg * idx / (n_samples - 1))
    return Protocol(angles, idx, idx, idx.astype(float), joint_specified=True)


def observe(centre, radius, angles_rad, sigma, rng) -> np.ndarray:
    """Noisy samples z_i = c + r[cos φ_i, sin φ_i] + N(0, σ² I₂), shape (n, 2), m."""
    clean = centre + radius * np.column_stack([np.cos(angles_rad), np.sin(angles_rad)])
    return clean + rng.normal(0.0, sigma, clean.shape)


def fit_methods(points, protocol: Protocol) -> dict[str, tuple[np.ndarray, float]]:
    """Centre (2,) and radius of ``joint`` and ``separate``; NaNs where a fit is degenerate."""
    out = {}
    try:
        centre, radius, _, _ = fit_circle_constant_rate(points[protocol.joint_idx], protocol.joint_times)
        out["joint"] = (centre, radius)
    except DegenerateFitError:
        out["joint"] = (np.full(2, np.nan), np.nan)
    try:
        out["separate"] = fit_circle(points[protocol.separate_idx])
    except DegenerateFitError:
        out["separate"] = (np.full(2, np.nan), np.nan)
    return out


def bounds(protocol: Protocol, radius: float, sigma: float) -> dict[str, dict[str, float]]:
    """CRB rows: expected errors of an efficient estimator and the RMSE bounds (m)."""
    rows = {}
    crb = crb_circle_nuisance_angles(protocol.angles_rad[protocol.separate_idx], sigma)
    blocks = {"crb": crb[:3, :3]}
    if protocol.joint_specified:
        angles = protocol.angles_rad[protocol.joint_idx]
        blocks["crb_joint"] = crb_circle_constant_rate(angles, protocol.joint_times, radius, sigma)[:3, :3]
    for name, C in blocks.items():
        rows[name] = {"centre_error": expected_norm_gaussian_2d(C[:2, :2]),
                      "radius_error": expected_abs_gaussian(C[2, 2]),
                      "centre_rmse": float(np.sqrt(np.trace(C[:2, :2]))),
                      "radius_rmse": float(np.sqrt(C[2, 2]))}
    return rows


def _seed_rows(settings: Settings, protocol: Protocol, k: int) -> list[dict]:
    """Errors of joint and separate on run k (seed settings.seed + k)."""
    rng = np.random.default_rng(settings.seed + k)
    points = observe(settings.centre, settings.radius, protocol.angles_rad, settings.noise_sigma, rng)
    return [{"seed": settings.seed + k, "method": method,
             "centre_error": float(np.linalg.norm(centre - settings.centre)),
             "radius_error": float(abs(radius - settings.radius))}
            for method, (centre, radius) in fit_methods(points, protocol).items()]


def monte_carlo(settings: Settings, protocol: Protocol, n_runs: int, desc: str | None = None,
                seeds: SeedRunner | None = None) -> pd.DataFrame:
    """Per-run errors of joint and separate, seeds settings.seed + k, k < n_runs.

    With ``desc`` the runs go through ``seeds`` (:mod:`stslam.experiments.seeds`, a bar named ``desc``)
    in units of :data:`SEED_BLOCK`; without, one after another here.
    """
    work = functools.partial(_seed_rows, settings, protocol)
    if desc is None:
        per_run = [work(k) for k in range(n_runs)]
    else:
        per_run = (seeds or SeedRunner()).map(work, n_runs, desc, settings.progress, block=SEED_BLOCK)
    rows = [row for run_rows in per_run for row in run_rows]
    return pd.DataFrame(rows, columns=["seed", "method", "centre_error", "radius_error"])


def _rmse_stats(errors: np.ndarray) -> tuple[float, float, float, float, int]:
    """RMSE, root median square, and the 95% interval of the RMSE from that of the MSE."""
    sq = errors[np.isfinite(errors)] ** 2
    mse, low, high = mean_ci(sq)
    root = np.sqrt(np.maximum(np.array([mse, low, high]), 0.0))  # NaN stays NaN
    median = float(np.sqrt(np.median(sq))) if sq.size else float("nan")
    return float(root[0]), median, float(root[1]), float(root[2]), int(sq.size)


def rmse_summary(runs: pd.DataFrame, crb_rows: dict) -> pd.DataFrame:
    """``centre_rmse`` and ``radius_rmse`` rows in the summary.csv layout (SPEC 12)."""
    rows = []
    for method in pd.unique(runs["method"]):
        block = runs[runs["method"] == method]
        for metric, column in (("centre_rmse", "centre_error"), ("radius_rmse", "radius_error")):
            rmse, median, low, high, n = _rmse_stats(block[column].to_numpy(dtype=float))
            rows.append([method, metric, rmse, median, low, high, n])
    n_seeds = int(runs["seed"].nunique())
    for method, values in crb_rows.items():
        for metric in ("centre_rmse", "radius_rmse"):
            v = values[metric]
            rows.append([method, metric, v, v, v, v, n_seeds])
    return pd.DataFrame(rows, columns=SUMMARY_COLUMNS)


def run_sweep(settings: Settings) -> pd.DataFrame:
    """RMSE of joint and separate (fair protocol) and both bounds over arc length and sample count.

    Also the median errors of the fits: on short arcs the fits have no finite
    moments (a nearly straight arc admits circles of any size), so the RMSE there
    is set by a few wild runs while the median stays informative.
    """
    grid = [("arc_deg", a, settings.n_samples) for a in settings.sweep_arcs_deg]
    grid += [("n_samples", settings.arc_deg, n) for n in settings.sweep_n_samples]
    rows = []
    for swept, arc, n in progress(grid, "structure_fit sweep", total=len(grid), enabled=settings.progress):
        protocol = fair_protocol(arc, n, settings.start_deg)
        runs = monte_carlo(settings, protocol, settings.sweep_n_seeds)
        summary = rmse_summary(runs, bounds(protocol, settings.radius, settings.noise_sigma))
        wide = summary.pivot(index="method", columns="metric", values="mean")
        medians = runs.groupby("method")[["centre_error", "radius_error"]].median()
        for method in ("separate", "joint", "crb", "crb_joint"):
            rows.append({"swept": swept, "arc_deg": arc, "n_samples": n, "method": method,
                         "centre_rmse": wide.loc[method, "centre_rmse"],
                         "radius_rmse": wide.loc[method, "radius_rmse"],
                         "centre_ratio_to_crb": wide.loc[method, "centre_rmse"] / wide.loc["crb", "centre_rmse"],
                         "radius_ratio_to_crb": wide.loc[method, "radius_rmse"] / wide.loc["crb", "radius_rmse"],
                         "centre_median_error": medians["centre_error"].get(method, np.nan),
                         "radius_median_error": medians["radius_error"].get(method, np.nan),
                         "n_runs": settings.sweep_n_seeds})
    return pd.DataFrame(rows)


def comparison_table(summary: pd.DataFrame, methods, protocol: str) -> pd.DataFrame:
    """Wide table: per method the four metrics and, in the paper protocol, the paper's corrected Table I."""
    wide = summary.pivot_table(index="method", columns="metric", values="mean", sort=False)
    rows = []
    for method in methods:
        row = {"method": method}
        for metric in ("centre_error", "radius_error", "centre_rmse", "radius_rmse"):
            row[metric] = float(wide.loc[method, metric])
        paper = PAPER_TABLE_I if protocol == "paper" else {}
        row["paper_centre_error"] = paper.get((method, "centre_error"), np.nan)
        row["paper_radius_error"] = paper.get((method, "radius_error"), np.nan)
        rows.append(row)
    return pd.DataFrame(rows)


def _format_lines(settings: Settings, table: pd.DataFrame) -> list[str]:
    def num(v):
        return "   --" if not np.isfinite(v) else f"{v:7.4f}"

    head = (f"structure_fit: protocol={settings.protocol}"
            + ("" if settings.protocol == "paper" else f" arc={settings.arc_deg:g}° n={settings.n_samples}")
            + f", {settings.n_seeds} seeds, σ={settings.noise_sigma:g} m")
    lines = [head, "method      centre_err radius_err centre_rmse radius_rmse | paper (Table I, corrected)"]
    for _, r in table.iterrows():
        lines.append(f"{r['method']:<10} {num(r['centre_error'])}    {num(r['radius_error'])}    "
                     f"{num(r['centre_rmse'])}     {num(r['radius_rmse'])}   | "
                     f"{num(r['paper_centre_error'])} {num(r['paper_radius_error'])}")
    by = table.set_index("method")
    ratio = by.loc["separate", "centre_rmse"] / by.loc["crb", "centre_rmse"]
    lines.append(f"separate/crb centre_rmse = {ratio:.3f} (SPEC 11 target ≤ {CRB_TARGET_RATIO} for arcs ≥ 90°)")
    return lines


def run(cfg: dict, seeds: SeedRunner | None = None) -> ExperimentOutput:
    """Monte Carlo of joint and separate fits beside the CRB, the sweep and the figures (SPEC 8.1);
    ``seeds`` runs the Monte Carlo runs (:mod:`stslam.experiments.seeds`; None: one after another here)."""
    settings = read_settings(cfg)
    protocol = (paper_protocol() if settings.protocol == "paper"
                else fair_protocol(settings.arc_deg, settings.n_samples, settings.start_deg))
    crb_rows = bounds(protocol, settings.radius, settings.noise_sigma)
    runs = monte_carlo(settings, protocol, settings.n_seeds, desc="structure_fit seeds", seeds=seeds)
    crb_frames = [pd.DataFrame({"seed": runs["seed"].unique(), "method": name,
                                "centre_error": v["centre_error"], "radius_error": v["radius_error"]})
                  for name, v in crb_rows.items()]
    metrics = pd.concat([runs, *crb_frames], ignore_index=True)
    metrics = metrics.sort_values(["seed"], kind="stable").reset_index(drop=True)
    extra = rmse_summary(runs, crb_rows)
    summary = pd.concat([summarise(metrics), extra], ignore_index=True)
    methods = ["joint", "separate", *crb_rows]
    table = comparison_table(summary, methods, settings.protocol)

    rng = np.random.default_rng(settings.seed)
    points = observe(settings.centre, settings.radius, protocol.angles_rad, settings.noise_sigma, rng)
    figures = {"single_run": single_run_figure(points, protocol.joint_idx, fit_methods(points, protocol),
                                               settings.centre, settings.radius, settings.protocol)}
    tables = {"table1": table, "rmse": extra}
    if settings.sweep_n_seeds > 0 and (settings.sweep_arcs_deg or settings.sweep_n_samples):
        sweep = run_sweep(settings)
        tables["sweep"] = sweep
        figures["sweep"] = sweep_figure(sweep, settings.n_samples, settings.arc_deg, settings.noise_sigma)
    return ExperimentOutput(metrics=metrics, figures=figures, tables=tables,
                            lines=_format_lines(settings, table), summary_extra=extra)
