"""Run one experiment from a resolved configuration and write its results folder."""

from __future__ import annotations

import os
import time
from pathlib import Path

from stslam import experiments
from stslam.errors import ConfigError
from stslam.config.readers import get_int, lookup
from stslam.experiments.resume import abandon, seed_runner
from stslam.io.results import write_run

# Distributions whose versions every results folder records (version.json, SPEC 12).
TRACKED_PACKAGES = (
    "numpy", "scipy", "pandas", "matplotlib", "filterpy", "hydra-core", "omegaconf",
    "mcap", "mcap-protobuf-support", "foxglove-schemas-protobuf", "protobuf",
    "opencv-python-headless", "evo", "numba",
)


def execute(config: dict, argv: list[str] | None = None, in_sweep: bool = False) -> Path:
    """Run ``config["exp_name"]`` and write ``<out_dir>/<exp>/<stamp>-<sha>/``.

    The configuration is checked by the experiment before any work starts and no
    results folder is written unless the run completes (SPEC 12). The seeds of a
    multi-seed experiment are run by :mod:`stslam.experiments.seeds` (``jobs``)
    and kept as they finish, so an interrupted run can be continued with
    ``resume=true`` (:mod:`stslam.experiments.resume`; ``in_sweep``: this is one
    job of a Hydra sweep).
    """
    name = lookup(config, "exp_name", None)
    if name is None:
        names = experiments.EXPERIMENTS + experiments.USER_INPUT_RUNS
        raise ConfigError("exp: no experiment chosen; add +exp=<name> with one of " + ", ".join(names))
    module = experiments.load(name)
    get_int(config, "seed", low=0)
    get_int(config, "n_seeds", low=1)
    out_dir = _writable_out_dir(config, name)
    seeds = seed_runner(config, name, out_dir, argv, in_sweep)
    started = time.monotonic()
    try:
        output = module.run(config, seeds) if name in experiments.MULTI_SEED else module.run(config)
        try:
            folder = write_run(out_dir, name, config, output, seed=config["seed"], argv=argv,
                               packages=TRACKED_PACKAGES, duration_s=time.monotonic() - started,
                               folder=seeds.checkpoints.folder if seeds.checkpoints else None,
                               resumed_seeds=seeds.resumed_seeds, jobs=seeds.jobs)
        except OSError as error:  # disk full, permissions changed during the run …
            raise ConfigError(f"out_dir: cannot write the results folder under {out_dir / name}: "
                              f"{error.strerror or error}") from None
        finally:
            _close_figures(output.figures)
    except BaseException as error:
        abandon(seeds, error)  # finished seeds kept (and how to continue said), or no folder left
        raise
    if seeds.checkpoints is not None:
        seeds.checkpoints.close()
    for line in output.lines:
        print(line)
    if seeds.resumed_seeds or seeds.workers_used > 1:
        where = (f"{seeds.workers_used} worker processes at once, each at most {seeds.peak_worker_kib / 1024:.0f} MiB "
                 f"resident (the main process {_peak_rss_mib():.0f} MiB)" if seeds.workers_used > 1
                 else "the rest computed in this process")
        print(f"seeds: {seeds.done_seeds}, {seeds.resumed_seeds} of them from an earlier run's checkpoints; {where}")
    print(f"results: {folder}")
    return folder


def _writable_out_dir(config: dict, name: str) -> Path:
    """``out_dir`` as a Path, checked before the run: its nearest existing ancestor is a writable folder.

    Nothing is created here, so a run rejected later leaves no trace (SPEC 12).
    """
    out_dir = lookup(config, "out_dir")
    if isinstance(out_dir, bool) or not isinstance(out_dir, (str, int)) or str(out_dir) == "":
        raise ConfigError(f"out_dir: expected a folder path, got {out_dir!r}")
    existing = Path(str(out_dir)) / name
    while not existing.exists() and existing.parent != existing:
        existing = existing.parent
    if not existing.is_dir():
        raise ConfigError(f"out_dir: {existing} is not a folder; expected a folder for the results")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise ConfigError(f"out_dir: cannot create folders in {existing} (no write permission)")
    return Path(str(out_dir))


def _peak_rss_mib() -> float:
    """Largest resident memory of this process so far (MiB; ru_maxrss is in KiB on Linux, bytes on macOS)."""
    import resource
    import sys

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2**20 if sys.platform == "darwin" else peak / 1024


def _close_figures(figures) -> None:
    import matplotlib.pyplot as plt

    for figure in figures.values():
        plt.close(figure)
