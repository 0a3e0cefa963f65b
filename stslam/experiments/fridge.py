"""The fridge-door experiment (SPEC 8.5, paper §VII-E, Table III).

Per recording (a generated sequence per seed, or the user's ``mcap=<path>``):
front end (:mod:`stslam.rgbd.tracks`) → landmarks = the longest tracks →
the ``dynamic_slam`` filters and the same A-SLAM (:mod:`stslam.slam`, inputs
from :mod:`stslam.rgbd.slam_inputs`) → hinge axis from the tracks A-SLAM classified
revolute (:mod:`stslam.articulation.hinge_axis`), their points mapped to
the world with A-SLAM's poses (and, as an upper bound, with the true poses).

metrics.csv, per seed and method: ``ate_m``, ``rpe_m`` (δ = ``rpe_delta``
frames), ``nees``; ``odometry`` is the dead-reckoning baseline; the
``a_slam`` row also has ``axis_angle_deg``, ``axis_dist_m`` (A-SLAM poses),
``axis_angle_deg_true_poses``, ``axis_dist_m_true_poses`` and
``n_revolute`` (landmarks held revolute).
"""

from __future__ import annotations

from dataclasses import astuple

import time
from pathlib import Path

import numpy as np
import pandas as pd

from stslam.articulation.models import get_model
from stslam.rgbd.sequence import DataRequest
from stslam.experiments.datasets import generate
from stslam.errors import ConfigError, DegenerateFitError
from stslam.config.rgbd import sequence_from_config, topics_from_config, tracker_from_config
from stslam.articulation.hinge_axis import estimate_hinge_axis
from stslam.io.mcap_topics import DEFAULT_TOPICS, DEPTH_WRITE_ENCODINGS
from stslam.eval.metrics import ate_rmse, axis_angle_deg, axis_line_distance, rpe_rmse
from stslam.config.scene import scene_seed_indices
from stslam.experiments.scene import fridge_scene, scene_file
from stslam.slam.scene_record import SceneRecorder
from stslam.rgbd.track_errors import track_error_summary, track_error_table
from stslam.experiments.fridge_outputs import (not_computed, not_computed_lines, not_computed_table,
                                              structure_table)
from stslam.output import ExperimentOutput
from stslam.config.readers import get_choice, get_float, get_float_list, get_int, get_name_list, lookup, run_settings
from stslam.experiments.seeds import SeedRunner
from stslam.render.fridge import mu_figure, tracks_axis_figure, trajectories_figure
from stslam.rgbd.slam_inputs import inputs_from_tracks, select_landmarks
from stslam.rgbd.tracks import collect_tracks, world_points
from stslam.slam.consistency import pose_nees
from stslam.config.slam import (filter_params_from_config, hinge_axis_from_config, motion_noise_order_from_config,
                                update_iterations_from_config)
from stslam.config.backend import backend_description, backend_runner_from_config
from stslam.slam.filters import make_filter
from stslam.graph.run import online_scores
from stslam.eval.stats import mean_ci
from stslam.io.tum import tum_from_planar

METHODS = ("ekf_slam", "dyn_slam", "ekf_slam_gated", "a_slam")
# The paper's Table III (one real recording, ATE / RPE in metres).
PAPER_TABLE_III = {"ekf_slam": (0.059, 0.073), "dyn_slam": (0.055, 0.072), "a_slam": (0.123, 0.137)}


def _methods(cfg) -> list[str]:
    """The ``methods`` list: non-empty, known names, no repeats."""
    return get_name_list(cfg, "methods", METHODS)


def _recordings(cfg, seed: int, n_seeds: int) -> list[tuple[int, Path, DataRequest | None]]:
    """(seed, path, what to generate or None) per run; generated files are named by size and seed."""
    mcap = lookup(cfg, "mcap", None)
    if mcap is not None:
        if not isinstance(mcap, str) or not mcap:
            raise ConfigError(f"mcap: expected a file path or null, got {mcap!r}")
        return [(seed, Path(mcap), None)]
    data_dir = lookup(cfg, "data_dir")
    if not isinstance(data_dir, str) or not data_dir:
        raise ConfigError(f"data_dir: expected a folder path, got {data_dir!r}")
    sequence = sequence_from_config(lookup(cfg, "sequence"))  # checked before any work
    encoding = get_choice(cfg, "sequence.depth_encoding", DEPTH_WRITE_ENCODINGS)
    out = []
    for k in range(n_seeds):
        path = Path(data_dir) / f"fridge_{sequence.width}x{sequence.height}_seed{seed + k}.mcap"
        out.append((seed + k, path, DataRequest(seed=seed + k, out=path, sequence=sequence, depth_encoding=encoding)))
    return out


def axis_errors(tracks, poses_xytheta, revolute_ids, truth_point, truth_direction, options) -> tuple:
    """Hinge axis from the revolute tracks mapped with ``poses_xytheta`` and its errors (deg, m).

    Returns (HingeAxis or None, angle error °, line distance m); NaN errors when no axis could be fitted.
    """
    revolute = get_model("revolute")
    axes, sets = {}, {}
    for i in revolute_ids:
        ks, z, _ = tracks.track_robot(i)
        points = world_points(poses_xytheta, ks, z)
        try:
            structure = revolute.fit(points)
        except DegenerateFitError:
            continue
        axes[i] = (structure.axis_point, structure.axis_direction)
        sets[i] = points
    try:
        axis = estimate_hinge_axis(axes, sets, options)
    except DegenerateFitError:
        return None, float("nan"), float("nan")
    if not (np.all(np.isfinite(truth_point)) and np.all(np.isfinite(truth_direction))):
        return axis, float("nan"), float("nan")  # no door ground truth (fridge_outputs.not_computed)
    return (axis, axis_angle_deg(axis.direction_world, truth_direction),
            axis_line_distance(axis.point_world, axis.direction_world, truth_point, truth_direction))


def _score(tracks, poses, covs, rpe_delta: int) -> dict:
    if not tracks.has_ground_truth:
        return {"ate_m": float("nan"), "rpe_m": float("nan"), "nees": float("nan")}
    gt = tum_from_planar(tracks.times_s, tracks.poses_gt_xytheta)
    est = tum_from_planar(tracks.times_s, poses)
    nees = float(np.mean(pose_nees(tracks.poses_gt_xytheta, poses, covs))) if covs is not None else float("nan")
    return {"ate_m": ate_rmse(gt, est), "rpe_m": rpe_rmse(gt, est, delta=rpe_delta), "nees": nees}


def run_recording(cfg_parts: dict, tracks, seed: int, observer=None) -> dict:
    """All methods on one recording's tracks; rows, pose tracks, A-SLAM result, axes and timings.

    ``observer(k, state)``, if given, watches A-SLAM's run (e.g. a scene recorder; it must not change the state).
    """
    ids = select_landmarks(tracks, cfg_parts["min_track_frames"], cfg_parts["max_landmarks"])
    inputs = inputs_from_tracks(tracks, ids, cfg_parts["alpha"])
    rows, poses, seconds = [], {"odometry": tracks.poses_odom_xytheta}, {}
    rows.append({"seed": seed, "method": "odometry",
                 **_score(tracks, tracks.poses_odom_xytheta, None, cfg_parts["rpe_delta"])})
    aslam = None
    axes = {}
    for name in cfg_parts["methods"]:
        started = time.perf_counter()
        track = cfg_parts["run_filter"](cfg_parts["specs"][name], inputs, observer if name == "a_slam" else None)
        if name == "a_slam":
            aslam = track
        seconds[name] = time.perf_counter() - started
        poses[name] = track.poses_xytheta
        row = {"seed": seed, "method": name,
               **_score(tracks, track.poses_xytheta, track.pose_covs, cfg_parts["rpe_delta"]),
               **online_scores(track, lambda p, c: _score(tracks, p, c, cfg_parts["rpe_delta"]))}  # SPEC 14
        if name == "a_slam":
            revolute = sorted(i for i, r in aslam.landmarks.items() if r.model == "revolute")
            for label, source in (("", track.poses_xytheta), ("_true_poses", tracks.poses_gt_xytheta)):
                if label and not tracks.has_ground_truth:
                    row[f"axis_angle_deg{label}"] = row[f"axis_dist_m{label}"] = float("nan")
                    continue
                axis, angle, dist = axis_errors(tracks, source, revolute, tracks.hinge_point_world,
                                                tracks.hinge_axis_world, cfg_parts["axis"])
                axes[label or "a_slam"] = axis
                row[f"axis_angle_deg{label}"] = angle
                row[f"axis_dist_m{label}"] = dist
            row["n_revolute"] = len(revolute)
        rows.append(row)
    return {"rows": rows, "poses": poses, "aslam": aslam, "axes": axes, "seconds": seconds, "landmarks": ids}


def _cell(values) -> str:
    values = np.asarray(values, dtype=float)
    mean, low, high = mean_ci(values)
    ci = f" [{low:.4f}, {high:.4f}]" if np.isfinite(low) else ""
    return f"{mean:.4f}{ci}"


def summary_lines(metrics: pd.DataFrame, header: list[str]) -> list[str]:
    """Table III beside ours (mean [95% CI] over seeds) and the hinge-axis errors per seed."""
    lines = list(header)
    lines.append(f"{'method':15s} {'paper ATE/RPE':>14s}  {'ATE m: mean [95% CI]':>28s}  {'RPE m: mean [95% CI]':>28s}")
    for method, block in metrics.groupby("method", sort=False):
        paper = PAPER_TABLE_III.get(method)
        paper_text = f"{paper[0]:.3f}/{paper[1]:.3f}" if paper else "-"
        lines.append(f"{method:15s} {paper_text:>14s}  {_cell(block['ate_m']):>28s}  {_cell(block['rpe_m']):>28s}")
    if "axis_angle_deg" in metrics:
        rows = metrics[metrics["method"] == "a_slam"]
        for _, r in rows.iterrows():
            lines.append(f"seed {int(r['seed'])}: hinge axis {r['axis_angle_deg']:.2f}° / "
                         f"{r['axis_dist_m'] * 100:.1f} cm (A-SLAM poses), {r['axis_angle_deg_true_poses']:.2f}° / "
                         f"{r['axis_dist_m_true_poses'] * 100:.1f} cm (true poses), {int(r['n_revolute'])} revolute")
        ok = (rows["axis_angle_deg"] <= 5.0) & (rows["axis_dist_m"] <= 0.05)
        lines.append(f"hinge axis within 5° and 5 cm on {int(ok.sum())}/{len(rows)} seeds")
    ate = metrics.pivot(index="seed", columns="method", values="ate_m")
    if "a_slam" in ate and ate["a_slam"].isna().all():  # no ground truth: nothing to compare
        return lines
    if {"a_slam", "ekf_slam"} <= set(ate.columns):
        lines.append(f"a_slam ATE ≤ ekf_slam on {int((ate['a_slam'] <= ate['ekf_slam']).sum())}/{len(ate)} seeds")
    if {"a_slam", "ekf_slam_gated"} <= set(ate.columns):
        lines.append(f"a_slam ATE ≤ ekf_slam_gated on {int((ate['a_slam'] <= ate['ekf_slam_gated']).sum())}/"
                     f"{len(ate)} seeds")
    return lines


def run(cfg: dict, seeds: SeedRunner | None = None) -> ExperimentOutput:
    """Run the fridge pipeline on every recording (SPEC 8.5); ``seeds`` runs them (:mod:`stslam.experiments.seeds`)."""
    # Configuration first (SPEC 12): one line naming a bad parameter, before any work.
    seed, n_seeds, show_progress = astuple(run_settings(cfg))
    methods = _methods(cfg)
    rpe_delta = get_int(cfg, "rpe_delta", low=1)
    recordings = _recordings(cfg, seed, n_seeds)
    plot_seed = get_int(cfg, "plot_seed", low=0, high=len(recordings) - 1)
    scene_seeds, scenes = scene_seed_indices(cfg, len(recordings)), {}
    frontend = tracker_from_config(cfg, "frontend")
    topics = topics_from_config(cfg, "mcap_topics")
    get_float(cfg, "sequence.rate_hz", low=0.0, low_open=True)
    parts = {
        "methods": methods, "rpe_delta": rpe_delta,
        "alpha": get_float_list(cfg, "odometry_alpha", length=4, low=0.0),
        "min_track_frames": get_int(cfg, "landmarks.min_track_frames", low=2),
        "max_landmarks": get_int(cfg, "landmarks.max_landmarks", low=1, high=1000),
        # The dynamic_slam filters and A-SLAM (stslam.slam), on every landmark track alike.
        "specs": {m: make_filter(m, filter_params_from_config(cfg, m), None, motion_noise_order_from_config(cfg),
                                 update_iterations_from_config(cfg))
                  for m in methods},
        "axis": hinge_axis_from_config(cfg, "axis", defaults=False),
        "run_filter": backend_runner_from_config(cfg),  # EKF or iSAM2 (SPEC 14)
    }

    def one_recording(k: int) -> dict:
        """Recording k (made first if it is a generated one not on disk yet): its rows, tables, TUM files
        and scene; its tracks and result when the figures show it."""
        run_seed, path, request = recordings[k]
        done = {"lines": [], "trajectories": {}, "structure": None, "scene": None, "plotted": None}
        if request is not None and not path.exists():
            path.parent.mkdir(parents=True, exist_ok=True)
            done["lines"] = generate(request).lines()[:1]
        # A generated sequence has the default names; mcap_topics names those of the recording given as mcap=.
        tracks = collect_tracks(path, frontend, topics=topics if request is None else DEFAULT_TOPICS)
        done["fps"] = tracks.n_frames / tracks.frontend_seconds
        recorder = SceneRecorder() if k in scene_seeds else None
        result = run_recording(parts, tracks, run_seed, recorder)
        done["rows"] = result["rows"]
        done["missing"] = not_computed(tracks)
        if result["aslam"] is not None:
            done["structure"] = structure_table(run_seed, tracks, result["poses"]["a_slam"],
                                                result["aslam"].landmarks, result["axes"].get("a_slam"))
        if tracks.has_ground_truth:
            done["trajectories"][f"groundtruth_seed{run_seed}.tum"] = tum_from_planar(tracks.times_s,
                                                                                      tracks.poses_gt_xytheta)
        done["errors"] = track_error_table(tracks, result["landmarks"]).assign(seed=run_seed)
        for name, poses in result["poses"].items():
            done["trajectories"][f"{name}_seed{run_seed}.tum"] = tum_from_planar(tracks.times_s, poses)
        if k == plot_seed:
            done["plotted"] = (run_seed, tracks, result)
        if recorder is not None:
            done["scene"] = fridge_scene(tracks, result["poses"], recorder, result["aslam"])
        return done

    rows, trajectories, lines_extra, missing, structures, errors = [], {}, [], {}, [], []
    plotted = None
    fps = []
    for k, done in enumerate((seeds or SeedRunner()).map(one_recording, len(recordings), "fridge", show_progress)):
        run_seed = recordings[k][0]
        lines_extra.extend(done["lines"])
        fps.append(done["fps"])
        rows.extend(done["rows"])
        missing[run_seed] = done["missing"]
        if done["structure"] is not None:
            structures.append(done["structure"])
        errors.append(done["errors"])
        trajectories.update(done["trajectories"])
        if k == plot_seed:
            plotted = done["plotted"]
        if k in scene_seeds:
            scenes[scene_file(len(scene_seeds), run_seed)] = done["scene"]
    metrics = pd.DataFrame(rows)

    run_seed, tracks, result = plotted
    figures = {"trajectories": trajectories_figure(tracks.poses_gt_xytheta, result["poses"],
                                                   tracks.hinge_point_world, title=f"seed {run_seed}")}
    if result["aslam"] is not None:
        figures["tracks_axis"] = tracks_axis_figure(tracks, result["aslam"].landmarks, result["axes"].get("a_slam"),
                                                    title=f"seed {run_seed}, frame {tracks.snapshot_index}")
        figures["model_probabilities"] = mu_figure(tracks, result["aslam"].landmarks)
    width, height = tracks.image_size
    header = [*lines_extra,
              f"fridge: {len(recordings)} recording(s), {width} × {height}, {tracks.n_frames} frames; "
              f"landmarks: ≤ {parts['max_landmarks']} tracks with ≥ {parts['min_track_frames']} observations",
              f"front end: {np.mean(fps):.0f} frames/s (mean over recordings, wall clock, this machine)",
              backend_description(cfg)]
    tables = {"structures": pd.concat(structures, ignore_index=True)} if structures else {}
    errors = pd.concat(errors, ignore_index=True)
    if len(errors):  # the landmark tracks' errors against the ground truth (stslam.rgbd.track_errors)
        tables["track_errors"] = errors[["seed", *errors.columns.drop("seed")]]
    if any(missing.values()):
        tables["not_computed"] = not_computed_table(missing)
    return ExperimentOutput(metrics=metrics, figures=figures, trajectories=trajectories, tables=tables, binaries=scenes,
                            lines=summary_lines(metrics, header) + not_computed_lines(missing)
                            + track_error_summary(errors))
