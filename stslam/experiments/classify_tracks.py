"""Classify a user's point tracks (SPEC 10): which joint moved each marker.

Every file matching ``tracks.glob`` is read (:mod:`stslam.io.track_files`) and
run through model selection (SPEC 4) with the ``selection`` settings (by
default ``conf/selection/marker_tracks.yaml``: IMM, τ = 0.9 held for 0.5 s,
no decision before 0.1 m of motion). δt is 1/``tracks.rate_hz`` or, with
``tracks.time_column``, the file's own time steps.

metrics.csv has one row per file: ``seed`` (the run's seed; nothing here is
random), ``method`` (the selector), ``file``, ``model`` (static, prismatic,
revolute or undecided), ``selection_step`` (0-based row of the online decision, or the last row
when μ only passed τ by the end of the track), ``selection_time_s``
(from the first row), the final μ per model, the chosen model's structure
fitted on the whole track (revolute: ``axis_{x,y,z}`` unit axis,
``axis_point_{x,y,z}`` m, ``radius_m``; prismatic: ``direction_{x,y,z}``) and
``fit_residual_m``; files written by ``experiments/make_tracks.py`` carry
their ground truth, which adds ``true_model``, ``correct``, ``onset_s``,
``decision_delay_s`` (selection time minus motion onset) and, when the model
is right, the structure errors of SPEC 7 (``axis_angle_deg``: hinge axis or
drawer direction; ``axis_dist_m``, ``radius_error_m``: revolute), and ``kind``.

With revisable decisions (``selection.revise``, on in marker_tracks), ``model``
is the decision standing at the end and ``first_model``, ``first_step``,
``revisions``, ``decided_by`` and ``final_argmax`` tell how it came about
(docs/selection.md §1). With ``batch.enabled`` the batch baseline (MLESAC
fits chosen by BIC, docs/selection.md §3) adds ``batch_model``,
``batch_bic_<model>`` and ``batch_correct``; ``per_class.csv`` has the
accuracy of both and the median decision delay per kind of joint.

A file that cannot be read, or whose track cannot be classified (any error
of the algorithms on it), is listed in ``errors.csv`` and printed on one
line; the other files are still processed.
"""

from __future__ import annotations

import glob
from pathlib import Path

import numpy as np
import pandas as pd

from stslam.errors import ConfigError, InputFileError, StslamError
from stslam.eval.metrics import axis_angle_deg, axis_line_distance, radius_error
from stslam.output import ExperimentOutput
from stslam.config.readers import get_bool, get_float, get_int, lookup
from stslam.progress import progress
from stslam.render.tracks import tracks_overview
from stslam.selection.batch import batch_select
from stslam.selection.selector import select_track
from stslam.config.selection import batch_from_config, selection_from_config
from stslam.io.track_files import read_track_file


def _structure_columns(model: str | None, structure) -> dict:
    cols = {f"axis_{a}": np.nan for a in "xyz"} | {f"axis_point_{a}": np.nan for a in "xyz"}
    cols |= {"radius_m": np.nan} | {f"direction_{a}": np.nan for a in "xyz"} | {"fit_residual_m": np.nan}
    if structure is None:
        return cols
    if model == "revolute":
        cols |= {f"axis_{a}": v for a, v in zip("xyz", structure.axis_direction)}
        cols |= {f"axis_point_{a}": v for a, v in zip("xyz", structure.axis_point)}
        cols["radius_m"] = structure.radius
    elif model == "prismatic":
        cols |= {f"direction_{a}": v for a, v in zip("xyz", structure.direction)}
    cols["fit_residual_m"] = structure.residual_m
    return cols


def classify_track(track, settings, rate_hz: float, batch=None) -> tuple[dict, object, object]:
    """Selection over one :class:`~stslam.io.track_files.PointTrack`; returns (row, selector, structure).

    ``batch`` (:class:`~stslam.selection.batch.BatchSettings`), if given, adds the batch baseline's columns.
    """
    n = track.points_world.shape[0]
    times = track.times_s - track.times_s[0] if track.times_s is not None else np.arange(n) / rate_hz
    selector = select_track(track.points_world, settings.with_dt(1.0 / rate_hz),
                            times_s=track.times_s)
    model = selector.final_model()
    structure = selector.final_structure(model) if model is not None else None
    step = selector.decision_step()
    row = {
        "model": model or "undecided",
        "selection_step": np.nan if step is None else step,
        "selection_time_s": np.nan if step is None else float(times[step]),
        **{f"mu_{name}": float(m) for name, m in zip(selector.names, selector.mu)},
        **_structure_columns(model, structure),
    }
    if settings.revise:
        row |= _decision_columns(selector)
    if batch is not None:
        result = batch_select(track.points_world, batch, selector.names)
        row |= {"batch_model": result.model, **{f"batch_bic_{m}": float(v) for m, v in result.bic.items()}}
    truth = track.metadata.get("true_model")
    if truth is not None:
        onset = _metadata_vector(track.metadata, "onset_s", 1)
        row |= {"kind": track.metadata.get("kind", truth), "true_model": truth, "correct": int(model == truth),
                "onset_s": float(onset[0]),
                "decision_delay_s": row["selection_time_s"] - float(onset[0])}
        row |= _structure_errors(model if model == truth else None, structure, track.metadata)
        if batch is not None:
            row["batch_correct"] = int(row["batch_model"] == truth)
    return row, selector, structure


def _decision_columns(selector) -> dict:
    """The first decision, revisions, how the final one was made and the final arg-max (docs/selection.md §1)."""
    d = selector.decisions
    _, _, how = selector.final_decision()
    log_p = selector.decision_log_mu()
    return {"first_model": d.first or "undecided", "first_step": np.nan if d.first_step is None else d.first_step,
            "revisions": d.revisions, "decided_by": how,
            "final_argmax": selector.names[int(np.argmax(log_p))],
            # μ stops moving once a track settles; the decision probabilities (μ with the nested price) are what
            # the decision reads, so they are reported beside it
            **{f"p_{name}": float(np.exp(v)) for name, v in zip(selector.names, log_p)}}


def _metadata_vector(metadata: dict, key: str, size: int) -> np.ndarray:
    """Numbers of a ``# key: v1 v2 …`` header line; NaN when absent or malformed."""
    try:
        values = np.array([float(v) for v in metadata[key].split()])
    except (KeyError, ValueError):
        return np.full(size, np.nan)
    return values if values.shape == (size,) else np.full(size, np.nan)


def _structure_errors(model: str | None, structure, metadata: dict) -> dict:
    """Axis angle (deg), axis line distance (m) and radius error (m) against the file's ground truth (SPEC 7)."""
    out = {"axis_angle_deg": np.nan, "axis_dist_m": np.nan, "radius_error_m": np.nan}
    axis = _metadata_vector(metadata, "axis_direction", 3)
    point = _metadata_vector(metadata, "axis_point", 3)
    if structure is None or not np.all(np.isfinite(axis)) or np.linalg.norm(axis) == 0:
        return out
    if model == "revolute":
        out["axis_angle_deg"] = axis_angle_deg(structure.axis_direction, axis)
        if np.all(np.isfinite(point)):
            out["axis_dist_m"] = axis_line_distance(structure.axis_point, structure.axis_direction, point, axis)
        radius = _metadata_vector(metadata, "radius_m", 1)[0]
        out["radius_error_m"] = radius_error(structure.radius, radius) if np.isfinite(radius) else np.nan
    elif model == "prismatic":
        out["axis_angle_deg"] = axis_angle_deg(structure.direction, axis)
    return out


def run(cfg: dict) -> ExperimentOutput:
    """Classify every track file matching ``tracks.glob`` (SPEC 10)."""
    pattern = lookup(cfg, "tracks.glob")
    if not isinstance(pattern, str) or not pattern:
        raise ConfigError(f"tracks.glob: expected a file pattern (tracks=<glob>), got {pattern!r}")
    time_column = get_bool(cfg, "tracks.time_column")
    rate_hz = get_float(cfg, "tracks.rate_hz", low=0.0, low_open=True)
    max_figures = get_int(cfg, "max_figures", low=0)
    settings = selection_from_config(cfg, dt=1.0 / rate_hz)
    batch = batch_from_config(cfg, settings)
    seed = get_int(cfg, "seed", low=0)
    files = sorted(p for p in glob.glob(pattern, recursive=True) if Path(p).is_file())
    if not files:
        raise ConfigError(f"tracks.glob: no file matches {pattern!r}")

    rows, errors, shown, wrong = [], [], [], []  # panels of the overview: the first tracks, and wrong ones
    for path in progress(files, "classify_tracks", total=len(files), enabled=bool(lookup(cfg, "progress", False))):
        try:
            track = read_track_file(path, time_column=time_column, n_min=settings.n_min)
            row, selector, structure = classify_track(track, settings, rate_hz, batch)
        except InputFileError as error:
            errors.append({"file": error.path, "line": error.line, "problem": error.problem, "message": str(error)})
            continue
        except (StslamError, ValueError, ArithmeticError, np.linalg.LinAlgError) as error:  # one bad track never stops the batch
            problem = f"could not be classified: {type(error).__name__}: {str(error).splitlines()[0][:200]}"
            errors.append({"file": path, "line": None, "problem": problem, "message": f"{path}: {problem}"})
            continue
        rows.append({"seed": seed, "method": settings.selector, "file": path, **row})
        is_wrong = row.get("correct") == 0
        if len(shown) < max_figures or (is_wrong and len(wrong) < max_figures):
            panel = (track.points_world, row["model"], structure, f"{Path(path).name}: {row['model']}", is_wrong)
            (wrong if is_wrong else shown).append(panel)
    if not rows:
        first = errors[0]["message"]
        raise ConfigError(f"tracks.glob: none of the {len(files)} files matching {pattern!r} could be read "
                          f"(first: {first})")
    metrics = pd.DataFrame(rows)
    panels = (wrong + shown)[:max_figures]  # wrong classifications first: they are the ones to look at
    figures = {"tracks": tracks_overview(panels)} if panels else {}
    tables = {"errors": pd.DataFrame(errors, columns=["file", "line", "problem", "message"])}
    if "correct" in metrics:
        tables["per_class"] = per_class_table(metrics.dropna(subset=["true_model"]))
    lines = [f"error: {e['message']}" for e in errors] + _summary_lines(metrics)
    return ExperimentOutput(metrics=metrics, figures=figures, tables=tables, lines=lines)


def _summary_lines(metrics: pd.DataFrame) -> list[str]:
    counts = metrics["model"].value_counts()
    lines = [f"{len(metrics)} tracks: " + ", ".join(f"{m} {counts.get(m, 0)}"
                                                    for m in ("revolute", "prismatic", "static", "undecided"))]
    if "correct" in metrics:
        known = metrics.dropna(subset=["true_model"])
        delay = known["decision_delay_s"]
        lines.append(f"accuracy {known['correct'].mean():.1%} on {len(known)} tracks with ground truth; "
                     f"decision delay after motion onset: median {delay.median():.2f} s, "
                     f"max {delay.max():.2f} s, within 3 s: {(delay <= 3.0).mean():.1%}; "
                     f"median axis error {known['axis_angle_deg'].median():.2f}°")
        if "batch_correct" in known:
            lines.append(f"batch baseline (MLESAC + BIC): accuracy {known['batch_correct'].mean():.1%}")
        lines += [f"  {kind}: {row.n} tracks, online {row.online:.1%}, median delay {row.delay_s:.2f} s"
                  + (f", batch {row.batch:.1%}" if "batch" in row else "")
                  for kind, row in per_class_table(known).set_index("kind").iterrows()]
    return lines


def per_class_table(known: pd.DataFrame) -> pd.DataFrame:
    """Per kind of joint: tracks, online accuracy, median decision delay (s), batch accuracy if run."""
    groups = known.groupby("kind")
    table = pd.DataFrame({"n": groups.size(), "online": groups["correct"].mean(),
                          "delay_s": groups["decision_delay_s"].median()})
    if "batch_correct" in known:
        table["batch"] = groups["batch_correct"].mean()
    return table.reset_index()
