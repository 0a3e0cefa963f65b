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
drawer direction; ``axis_dist_m``, ``radius_error_m``: revolute). A bad file is
listed in ``errors.csv`` and printed; the other files are still processed.
"""

from __future__ import annotations

import glob
from pathlib import Path

import numpy as np
import pandas as pd

from stslam.errors import ConfigError, InputFileError
from stslam.eval.metrics import axis_angle_deg, axis_line_distance, radius_error
from stslam.output import ExperimentOutput
from stslam.config.readers import get_bool, get_float, get_int, lookup
from stslam.progress import progress
from stslam.render.tracks import track_figure
from stslam.selection.selector import select_track
from stslam.config.selection import selection_from_config
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


def classify_track(track, settings, rate_hz: float) -> tuple[dict, object, object]:
    """Selection over one :class:`~stslam.io.track_files.PointTrack`; returns (row, selector, structure)."""
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
    truth = track.metadata.get("true_model")
    if truth is not None:
        onset = _metadata_vector(track.metadata, "onset_s", 1)
        row |= {"true_model": truth, "correct": int(model == truth), "onset_s": float(onset[0]),
                "decision_delay_s": row["selection_time_s"] - float(onset[0])}
        row |= _structure_errors(model if model == truth else None, structure, track.metadata)
    return row, selector, structure


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
    seed = get_int(cfg, "seed", low=0)
    files = sorted(p for p in glob.glob(pattern, recursive=True) if Path(p).is_file())
    if not files:
        raise ConfigError(f"tracks.glob: no file matches {pattern!r}")

    rows, errors, figures = [], [], {}
    for path in progress(files, "classify_tracks", total=len(files), enabled=bool(lookup(cfg, "progress", False))):
        try:
            track = read_track_file(path, time_column=time_column, n_min=settings.n_min)
        except InputFileError as error:
            errors.append({"file": error.path, "line": error.line, "problem": error.problem, "message": str(error)})
            continue
        row, selector, structure = classify_track(track, settings, rate_hz)
        rows.append({"seed": seed, "method": settings.selector, "file": path, **row})
        if len(figures) < max_figures:
            name = f"{len(rows) - 1:03d}_{Path(path).stem}"
            figures[name] = track_figure(track.points_world, row["model"], structure,
                                         f"{Path(path).name}: {row['model']}")
    if not rows:
        first = errors[0]["message"]
        raise ConfigError(f"tracks.glob: none of the {len(files)} files matching {pattern!r} could be read "
                          f"(first: {first})")
    metrics = pd.DataFrame(rows)
    tables = {"errors": pd.DataFrame(errors, columns=["file", "line", "problem", "message"])}
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
    return lines
