"""Dynamic-world SLAM (SPEC 8.4, paper §VII-D, Table II).

Every method runs on the same simulated world, odometry and observations per
seed (seed k of a run uses ``default_rng(seed + k)``). Per seed and method:
``ate_m`` (rigid alignment, RMSE), ``rpe_m`` (δ = ``rpe_delta`` frames, RMSE),
``nees`` (robot-pose NEES averaged over frames 2…n−1) and ``nees_in_band``
(1 when that average lies in its 95% χ² band, with the frames' autocorrelation
time τ of that method over all seeds: :func:`nees_band_correlated`); A-SLAM's rows add
``correct``, ``moving_correct_frac``, ``selection_step`` and
``static_correct_frac`` (:func:`stslam.slam.decision_scores.selection_scores`; empty for
the other methods), which score only the movers seen moving
(:func:`stslam.slam.decision_scores.seen_moving`: observed at two times whose true
positions are over 5σ of the sensor apart); a mover never seen moving is
right when called static.
TUM files of the ground truth and of every method for every seed go to
``trajectories/``.
"""

from __future__ import annotations

from dataclasses import astuple

import numpy as np
import pandas as pd

from stslam.errors import ConfigError
from stslam.config.scene import scene_seed_indices
from stslam.experiments.scene import dynamic_slam_scene, scene_file
from stslam.slam.scene_record import SceneRecorder
from stslam.output import ExperimentOutput
from stslam.config.readers import get_bool, get_float, get_int, get_name_list, lookup, run_settings
from stslam.experiments.seeds import SeedRunner
from stslam.render.a_slam import decision_times_figure, model_probabilities_figure
from stslam.render.dynamic_slam import metric_boxplot, nees_over_time_figure, trajectories_figure
from stslam.config.robot import sensor_from_config
from stslam.slam.decision_scores import decision_rows, judged_rows, seen_moving, selection_scores
from stslam.slam.consistency import NEES_FIRST_FRAME, chi2_mean_band, nees_band, nees_band_correlated
from stslam.slam.consistency import pose_nees
from stslam.slam.evaluation import groundtruth_tum, run_seed, score_track, track_tum
from stslam.config.slam import filter_params_from_config, motion_noise_order_from_config, update_iterations_from_config
from stslam.config.backend import backend_description, backend_runner_from_config
from stslam.slam.filters import FILTER_NAMES, FilterTrack, make_filter
from stslam.graph.run import online_scores
from stslam.eval.stats import SUMMARY_COLUMNS, mean_ci
from stslam.config.sim import world_from_config

# The paper's Table II (one run, ATE / RPE in metres); RPE there is a mean over
# random frame pairs, ours an RMSE over consecutive frames (SPEC 8.4).
PAPER_TABLE_II = {"ekf_slam": (0.071, 0.087), "dyn_slam": (0.049, 0.051), "a_slam": (0.014, 0.003)}


def check_methods(cfg) -> list[str]:
    """The ``methods`` list: non-empty, known names, no repeats."""
    return get_name_list(cfg, "methods", FILTER_NAMES)


def method_runners(cfg, methods, world) -> dict:
    """Method name → callable SimulatedRun → FilterTrack, parameters checked now."""
    # A-SLAM's process noises default to the oracle's: check the oracle's first, so a bad
    # value is reported under the name the user set.
    order = motion_noise_order_from_config(cfg)
    iterations = update_iterations_from_config(cfg)
    specs = {name: make_filter(name, filter_params_from_config(cfg, name), world, order, iterations)
             for name in sorted(methods, key=lambda name: name == "a_slam")}
    runner = backend_runner_from_config(cfg)  # EKF or iSAM2 (SPEC 14)
    return {name: (lambda run, spec=specs[name], observer=None: runner(spec, run, observer)) for name in methods}


def _cell(values) -> str:
    mean, low, high = mean_ci(values)
    ci = f" [{low:.4f}, {high:.4f}]" if np.isfinite(low) else ""
    return f"{mean:.4f}{ci} ({np.median(values):.4f})"


def nees_bands(frame_nees: dict) -> dict:
    """Method → (low, high, τ): the 95% band of its NEES averaged over frames and seeds, frames
    autocorrelated (:func:`nees_band_correlated`; ``frame_nees[m]`` is (n_seeds, n_frames)). A method
    with a non-finite NEES somewhere (a singular pose covariance) gets NaNs: no band is meaningful."""
    nan = (float("nan"),) * 3
    return {m: nees_band_correlated(np.asarray(v)) if np.all(np.isfinite(v)) else nan for m, v in frame_nees.items()}


def nees_band_summary(bands: dict, n_seeds: int) -> pd.DataFrame:
    """``summary.csv`` rows per method: ``nees_band_low``, ``nees_band_high`` and ``nees_tau`` (in ``mean``)."""
    rows = [{"method": m, "metric": name, "mean": value, "median": value, "ci_low": float("nan"),
             "ci_high": float("nan"), "n": n_seeds}
            for m, band in bands.items() for name, value in zip(("nees_band_low", "nees_band_high", "nees_tau"), band)]
    return pd.DataFrame(rows, columns=SUMMARY_COLUMNS)


def flag_nees_in_band(metrics: pd.DataFrame, bands: dict, n_steps: int) -> pd.DataFrame:
    """Add ``nees_in_band`` after ``nees``: 1 when a seed's NEES lies in the one-seed band with its
    method's τ (SPEC 6.4), else 0."""
    flags = pd.Series(0, index=metrics.index)
    for method, (_, _, tau) in bands.items():
        low, high = chi2_mean_band(n_steps / tau)
        rows = metrics["method"] == method
        flags[rows] = ((metrics.loc[rows, "nees"] >= low) & (metrics.loc[rows, "nees"] <= high)).astype(int)
    out = metrics.copy()
    out.insert(out.columns.get_loc("nees") + 1, "nees_in_band", flags)
    return out


def nees_band_lines(metrics: pd.DataFrame, bands: dict, n_steps: int) -> list[str]:
    """Each method's NEES against its band with τ, and against the band of independent frames."""
    n_seeds = metrics["seed"].nunique()
    low, high = nees_band(n_steps, 3, n_seeds)
    lines = [f"NEES (robot pose, mean over frames {NEES_FIRST_FRAME}…{n_steps + NEES_FIRST_FRAME - 1} and "
             f"{n_seeds} seeds) against its 95% χ² band. Frames are autocorrelated (τ: integrated "
             f"autocorrelation time, frames per independent one); the band taking them as independent "
             f"is [{low:.3f}, {high:.3f}]:"]
    w = _name_width(metrics)
    for method, block in metrics.groupby("method", sort=False):
        if method not in bands:
            continue
        b_low, b_high, tau = bands[method]
        nees = block["nees"].mean()
        if not np.isfinite(tau):
            lines.append(f"  {method:{w}s} NEES {nees:6.3f}  band n/a (non-finite NEES on some frame)")
            continue
        verdict = "inside" if b_low <= nees <= b_high else ("above" if nees > b_high else "below")
        lines.append(f"  {method:{w}s} NEES {nees:6.3f}  band [{b_low:.3f}, {b_high:.3f}] (τ = {tau:4.1f}): {verdict}"
                     f"{'' if low <= nees <= high else '; outside the independent-frames band'}")
    return lines


def _name_width(metrics: pd.DataFrame) -> int:
    """Width of the printout's method column: 15, or the longest method name run."""
    return max(15, *(len(str(m)) for m in pd.unique(metrics["method"])))


def summary_lines(metrics: pd.DataFrame, seconds: dict, header: str) -> list[str]:
    """Table II beside ours: mean [95% CI] (median) of ATE and RPE, NEES, time per seed."""
    w = _name_width(metrics)
    lines = [header,
             f"{'method':{w}s} {'paper ATE/RPE':>14s}  {'ATE m: mean [95% CI] (median)':>36s}  "
             f"{'RPE m: mean [95% CI] (median)':>36s}  {'NEES':>8s}  {'s/seed':>7s}"]
    for method, block in metrics.groupby("method", sort=False):
        paper = PAPER_TABLE_II.get(method)
        paper_text = f"{paper[0]:.3f}/{paper[1]:.3f}" if paper else "-"
        lines.append(f"{method:{w}s} {paper_text:>14s}  {_cell(block['ate_m'].to_numpy()):>36s}  "
                     f"{_cell(block['rpe_m'].to_numpy()):>36s}  {block['nees'].mean():8.2f}  "
                     f"{np.mean(seconds[method]):7.3f}")
    for method, (ate, rpe) in PAPER_TABLE_II.items():
        if method not in set(metrics["method"]):
            lines.append(f"{method:{w}s} {ate:.3f}/{rpe:.3f}".ljust(w + 16) + "  (not run)")
    ate = metrics.pivot(index="seed", columns="method", values="ate_m")
    methods = list(pd.unique(metrics["method"]))
    for better in ("a_slam", "oracle", "ekf_slam_gated"):
        if better not in methods:
            continue
        for worse in methods:
            if worse != better and not (better != "a_slam" and worse in ("oracle", "a_slam")):
                wins = int((ate[better] < ate[worse]).sum())
                lines.append(f"{better} ATE below {worse} on {wins}/{len(ate)} seeds")
    if "a_slam" in methods:
        lines.extend(a_slam_lines(metrics))
    return lines


def divergence_warnings(metrics: pd.DataFrame) -> list[str]:
    """One WARNING line per method with diverged seeds (column ``diverged``, SPEC 6.4); printed last."""
    lines = []
    for method, block in metrics.groupby("method", sort=False):
        n_diverged = int(block["diverged"].sum())
        if n_diverged:
            lines.append(f"WARNING: {method} diverged on {n_diverged}/{len(block)} seeds (robot NEES above the "
                         f"χ²₃ 99.9% bound on more than 1/3 of frames, in a run of ≥ 10; column 'diverged')")
    return lines


def a_slam_lines(metrics: pd.DataFrame) -> list[str]:
    """A-SLAM's targets (SPEC 11): mean ATE against the oracle's, model decisions."""
    block = metrics[metrics["method"] == "a_slam"]
    lines = []
    if "oracle" in set(metrics["method"]):
        oracle_ate = metrics.loc[metrics["method"] == "oracle", "ate_m"].mean()
        lines.append(f"a_slam mean ATE / oracle mean ATE = {block['ate_m'].mean() / oracle_ate:.3f} (target ≤ 1.5)")
        truth = metrics.loc[metrics["method"] == "a_slam_truth_onsets", "ate_m"]
        if len(truth):  # SPEC 18: the same with perfect onsets, a bound
            lines.append(f"a_slam_truth_onsets mean ATE / oracle mean ATE = {truth.mean() / oracle_ate:.3f} "
                         f"(A-SLAM told by the simulation which observations moved: a bound, not an estimator)")
    steps = block["selection_step"].to_numpy(dtype=float)
    step_text = (f"; last moving landmark decided at observation {np.nanmedian(steps):.0f} (median)"
                 if np.isfinite(steps).any() else "")
    static = block["static_correct_frac"].to_numpy(dtype=float)
    static_text = (f"{np.nanmean(static):.3f} (mean fraction)" if np.isfinite(static).any()
                   else "none received a decision (see filters.a_slam.max_pose_sigma_m)")
    lines.append(f"a_slam: every moving landmark ends with its true model on {int(block['correct'].sum())}/"
                 f"{len(block)} seeds ({block['moving_correct_frac'].mean():.3f} of moving landmarks)"
                 f"{step_text}; static landmarks decided static: {static_text}")
    return lines


def model_probability_panels(world, track) -> list[dict]:
    """Panels of the μ figure: the most observed static landmark, then the first prismatic and revolute one."""
    panels = []
    for kind in ("static", "prismatic", "revolute"):
        candidates = [i for i, truth in enumerate(world.landmarks)
                      if truth.model_name == kind and i in track.landmarks and track.landmarks[i].mu_frames.size]
        if not candidates:
            continue
        i = max(candidates, key=lambda c: track.landmarks[c].mu_frames.size) if kind == "static" else candidates[0]
        report = track.landmarks[i]
        panels.append({"label": f"{world.landmarks[i].name} (true: {kind}; A-SLAM: {report.model})",
                       "frames": report.mu_frames, "mu": report.mu, "names": report.model_names,
                       "decisions": report.decisions})
    return panels


def run(cfg: dict, seeds: SeedRunner | None = None) -> ExperimentOutput:
    """Run every method of ``methods`` on ``n_seeds`` seeds of the configured world (SPEC 8.4).

    ``seeds`` runs the seeds (:mod:`stslam.experiments.seeds`; None: one after another here).
    """
    # Configuration first (SPEC 12): one line naming a bad parameter, before any work.
    seed, n_seeds, show_progress = astuple(run_settings(cfg))
    methods = check_methods(cfg)
    control_noise = get_bool(cfg, "robot.control_noise")
    get_float(cfg, "tau", low=0.0, high=1.0, low_open=True, high_open=True)  # A-SLAM's threshold (SPEC 4)
    rpe_delta = get_int(cfg, "rpe_delta", low=1)
    plot_seed = get_int(cfg, "plot_seed", low=0, high=n_seeds - 1)
    world = world_from_config(cfg)
    if rpe_delta >= world.n_frames:
        raise ConfigError(f"rpe_delta: expected < world.n_frames = {world.n_frames}, got {rpe_delta}")
    sensor = sensor_from_config(cfg)
    runners = method_runners(cfg, methods, world)
    scene_seeds, scenes = scene_seed_indices(cfg, n_seeds), {}

    def one_seed(k: int) -> dict:
        """Seed k's rows, TUM files, timings, per-frame NEES and A-SLAM's decisions; its whole result when a
        figure shows it."""
        decisions = []
        recorder = SceneRecorder() if k in scene_seeds and "a_slam" in runners else None
        result = run_seed(world, sensor, control_noise, runners, seed + k, rpe_delta,
                          {"a_slam": recorder} if recorder is not None else None)
        if "a_slam" in result.tracks:  # selection metrics of A-SLAM (SPEC 4, 12)
            # Movers never seen moving count as right when called static (SEEN_MOVING_SIGMAS).
            moved = seen_moving(world, result.run.observation_ids, sensor.sigma_m)
            scores = selection_scores(result.tracks["a_slam"], world, moved)
            decisions.extend({"seed": seed + k, **row} for row in decision_rows(result.tracks["a_slam"], world, moved))
            for row in result.rows:
                if row["method"] == "a_slam":
                    row.update(scores)
        for row in result.rows:  # iSAM2: the causal estimate beside the smoothed one (SPEC 14)
            row.update(online_scores(result.tracks[row["method"]], lambda poses, covs: score_track(
                world, FilterTrack(poses, covs, 0), pose_nees(world.poses_xytheta, poses, covs), rpe_delta)))
        tum = {f"groundtruth_seed{seed + k}.tum": groundtruth_tum(world)}
        tum.update({f"{name}_seed{seed + k}.tum": track_tum(world, track) for name, track in result.tracks.items()})
        return {"rows": result.rows, "trajectories": tum, "seconds": result.seconds, "frame_nees": result.frame_nees,
                "decisions": decisions,
                "plotted": result if k == plot_seed else None,
                "scene": dynamic_slam_scene(world, result, recorder) if k in scene_seeds else None}

    rows, trajectories, seconds, frame_nees = [], {}, {m: [] for m in methods}, {m: [] for m in methods}
    plotted, decisions = None, []
    for k, done in enumerate((seeds or SeedRunner()).map(one_seed, n_seeds, "dynamic_slam", show_progress)):
        rows.extend(done["rows"])
        decisions.extend(done.get("decisions", []))
        trajectories.update(done["trajectories"])
        for name in done["seconds"]:
            seconds[name].append(done["seconds"][name])
            frame_nees[name].append(done["frame_nees"][name])
        if k == plot_seed:
            plotted = done["plotted"]
        if k in scene_seeds:
            scenes[scene_file(len(scene_seeds), seed + k)] = done["scene"]
    metrics = pd.DataFrame(rows)

    header = (f"dynamic_slam: world {world.name}, sensor {lookup(cfg, 'sensor.fov')} σ={sensor.sigma_m} m, "
              f"control noise {'on' if control_noise else 'off'}, {n_seeds} seeds ({seed}…{seed + n_seeds - 1}); "
              f"{backend_description(cfg)}")
    paper = {m: PAPER_TABLE_II[m][0] for m in methods if m in PAPER_TABLE_II}
    figures = {
        "trajectories": trajectories_figure(
            world.poses_xytheta, {m: t.poses_xytheta for m, t in plotted.tracks.items()}, world.positions,
            title=f"{world.name}, seed {plotted.seed}"),
        "ate_per_seed": metric_boxplot(metrics, "ate_m", "ATE (m)", paper),
    }
    if "a_slam" in plotted.tracks:
        figures["model_probabilities"] = model_probabilities_figure(
            model_probability_panels(world, plotted.tracks["a_slam"]),
            title=f"A-SLAM model probabilities, {world.name}, seed {plotted.seed}")
    # SPEC 6.4, per frame: the NEES averaged over the seeds against the band of an n_seeds average
    # (Bar-Shalom, Li, Kirubarajan 2001, §5.4); a consistent filter stays inside on ~95% of frames.
    mean_nees = {m: np.mean(frame_nees[m], axis=0) for m in methods}
    band = nees_band(1, 3, n_seeds)
    figures["nees_over_time"] = nees_over_time_figure(
        np.arange(NEES_FIRST_FRAME, world.n_frames), mean_nees, band, title=f"{world.name}, {n_seeds} seeds")
    nees_line = (f"NEES per frame averaged over the {n_seeds} seeds, frames inside its 95% band "
                 f"[{band[0]:.2f}, {band[1]:.2f}] (≈95% for a consistent filter): "
                 + ", ".join(f"{m} {np.mean((v >= band[0]) & (v <= band[1])):.0%}" for m, v in mean_nees.items()))
    n_steps = world.n_frames - NEES_FIRST_FRAME
    bands = nees_bands(frame_nees)
    metrics = flag_nees_in_band(metrics, bands, n_steps)
    lines = [*summary_lines(metrics, seconds, header), *nees_band_lines(metrics, bands, n_steps),
             nees_line, *divergence_warnings(metrics)]
    tables = {}
    if decisions:  # A-SLAM's model per landmark (SPEC 18): the report's confusion table and decision times
        tables["decisions"] = pd.DataFrame(decisions)
        figures["decision_times"] = decision_times_figure(tables["decisions"], title=f"A-SLAM, {world.name}, "
                                                          f"{n_seeds} seeds")
        lines.append(confusion_line(tables["decisions"]))
    return ExperimentOutput(metrics=metrics, figures=figures, trajectories=trajectories, lines=lines, tables=tables,
                            summary_extra=nees_band_summary(bands, n_seeds), binaries=scenes)


def confusion_line(decisions: pd.DataFrame) -> str:
    """One line: A-SLAM's final models of the points seen moving and of the static ones, summed over seeds."""
    seen = judged_rows(decisions)
    table = pd.crosstab(seen["true_model"], seen["final_model"])
    return "a_slam final model (rows true, columns final, summed over seeds): " + "; ".join(
        f"{true}: " + ", ".join(f"{final} {int(n)}" for final, n in row.items() if n) for true, row in table.iterrows())
