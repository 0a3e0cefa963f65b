"""Versioned results folders (SPEC 12).

A run is written to ``<out_dir>/<exp>/.incomplete-<name>-<pid>`` and renamed to
``<out_dir>/<exp>/<YYYYmmdd-HHMMSS>-<git sha>[-<n>]`` once every file is in
place, so a folder without the leading dot is always complete. A folder name is
never reused: the final name is reserved with an atomic ``mkdir`` before the
(atomic) rename replaces the empty reservation. A run whose seeds were checkpointed
(:mod:`stslam.io.checkpoints`) writes into the incomplete folder its seeds were kept in, whose
checkpoints are removed just before the rename.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import shutil
import subprocess
import sys
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path

import pandas as pd
import yaml

from stslam.output import ExperimentOutput
from stslam.eval.stats import SUMMARY_COLUMNS, summarise
from stslam.io.checkpoints import INCOMPLETE_PREFIX, STATE_DIR
from stslam.io.tum import write_tum

REPO_ROOT = Path(__file__).resolve().parents[2]


def git_state(root: Path = REPO_ROOT) -> tuple[str, bool]:
    """Short git sha of ``root`` and whether its work tree is dirty ("nogit", False outside git)."""
    try:
        sha = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True,
                             text=True, check=True, timeout=10).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=root,
                               capture_output=True, text=True, check=True, timeout=10).stdout.strip()
        return sha or "nogit", bool(dirty)
    except (OSError, subprocess.SubprocessError):
        return "nogit", False


def version_info(seed: int | None, argv: list[str] | None = None, packages: Sequence[str] = (),
                 duration_s: float | None = None, resumed_seeds: int = 0, jobs: int = 1) -> dict:
    """Contents of ``version.json``: git state, versions of ``packages`` (None: not installed), python,
    seed, command line, when given the run's wall time in seconds (``duration_s``, of this process
    alone; ``experiments/reproduce.py`` estimates from it), the worker processes of its seeds
    (``jobs``) and how many seeds came from an earlier, interrupted run's checkpoints
    (``resumed_seeds``, ``resume=true``)."""
    sha, dirty = git_state()
    versions = {}
    for name in packages:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return {
        "git_sha": sha,
        "git_dirty": dirty,
        "packages": versions,
        "python": platform.python_version(),
        "seed": seed,
        "command": list(sys.argv if argv is None else argv),
        "duration_s": None if duration_s is None else round(float(duration_s), 3),
        "jobs": int(jobs),
        "resumed_seeds": int(resumed_seeds),
    }


def incomplete_stem(now: _dt.datetime | None = None) -> str:
    """Name of a run's temporary folder: ``.incomplete-<YYYYmmdd-HHMMSS>-<git sha>-<pid>``."""
    stamp = (now or _dt.datetime.now()).strftime("%Y%m%d-%H%M%S")
    return f"{INCOMPLETE_PREFIX}{stamp}-{git_state()[0]}-{os.getpid()}"


def _reserve_final_dir(parent: Path, stem: str) -> Path:
    """Atomically create an empty, never-used folder ``stem`` or ``stem-<n>``."""
    for n in range(0, 10_000):
        candidate = parent / (stem if n == 0 else f"{stem}-{n}")
        try:
            candidate.mkdir()
            return candidate
        except FileExistsError:
            continue
    raise RuntimeError(f"no free results folder name for {parent / stem}")


def write_run(out_dir, exp: str, config: dict, output: ExperimentOutput, *,
              seed: int | None = None, argv: list[str] | None = None, packages: Sequence[str] = (),
              now: _dt.datetime | None = None, duration_s: float | None = None,
              folder: Path | None = None, resumed_seeds: int = 0, jobs: int = 1) -> Path:
    """Write a complete results folder and return its final path.

    Parameters
    ----------
    out_dir : path
        Root of results (``out_dir`` override; default ``results``).
    exp : str
        Experiment name (the sub-folder).
    config : dict
        The resolved configuration, written as ``config.yaml``.
    output : ExperimentOutput
        Metrics, figures, trajectories and further tables of the run.
    packages : sequence of str
        Distributions whose versions ``version.json`` records.
    duration_s : float, optional
        Wall time of the run (s), recorded in ``version.json``.
    folder : Path, optional
        The run's incomplete folder, already made under ``<out_dir>/<exp>`` (it holds the seeds'
        checkpoints, removed before the rename); on failure it is left to the caller. Without it a
        temporary folder is made here and removed on failure.
    resumed_seeds, jobs : int
        Recorded in ``version.json`` (:func:`version_info`).
    """
    parent = Path(out_dir) / exp
    parent.mkdir(parents=True, exist_ok=True)
    stamp = (now or _dt.datetime.now()).strftime("%Y%m%d-%H%M%S")
    sha, _ = git_state()
    stem = f"{stamp}-{sha}"
    tmp = Path(folder) if folder is not None else parent / f"{INCOMPLETE_PREFIX}{stem}-{os.getpid()}"
    if folder is None:
        tmp.mkdir()
    try:
        _write_contents(tmp, config, output, seed, argv, packages, duration_s, resumed_seeds, jobs)
        shutil.rmtree(tmp / STATE_DIR, ignore_errors=True)  # the final folder holds the results alone
        final = _reserve_final_dir(parent, stem)
        os.rename(tmp, final)  # replaces the empty reservation atomically
    except BaseException:
        if folder is None:
            shutil.rmtree(tmp, ignore_errors=True)
        raise
    return final


def _write_contents(folder: Path, config: dict, output: ExperimentOutput, seed, argv, packages,
                    duration_s, resumed_seeds, jobs) -> None:
    (folder / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    (folder / "version.json").write_text(
        json.dumps(version_info(seed, argv, packages, duration_s, resumed_seeds, jobs), indent=2) + "\n")
    output.metrics.to_csv(folder / "metrics.csv", index=False)
    summary = summarise(output.metrics)
    if output.summary_extra is not None:
        summary = pd.concat([summary, output.summary_extra[SUMMARY_COLUMNS]], ignore_index=True)
    summary.to_csv(folder / "summary.csv", index=False)
    for name, table in output.tables.items():
        table.to_csv(folder / f"{name}.csv", index=False)
    for relative, text in output.files.items():
        target = folder / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(text)
    for relative, data in output.binaries.items():
        target = folder / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_bytes(data)
    if output.trajectories:
        (folder / "trajectories").mkdir(exist_ok=True)  # exists when an earlier write was cut short
        for name, rows in output.trajectories.items():
            write_tum(folder / "trajectories" / name, rows)
    (folder / "figures").mkdir(exist_ok=True)
    for name, figure in output.figures.items():
        # Fixed metadata keeps PDF/PNG bytes reproducible run to run.
        figure.savefig(folder / "figures" / f"{name}.pdf", metadata={"CreationDate": None})
        figure.savefig(folder / "figures" / f"{name}.png", dpi=150)


def complete_runs(out_dir, exp: str) -> list[Path]:
    """Finished results folders of ``exp``, oldest first (hidden temporaries excluded)."""
    parent = Path(out_dir) / exp
    if not parent.is_dir():
        return []
    runs = [p for p in parent.iterdir()
            if p.is_dir() and not p.name.startswith(".") and (p / "summary.csv").is_file()]
    return sorted(runs, key=lambda p: p.name)
