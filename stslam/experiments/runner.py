"""Run one experiment from a resolved configuration and write its results folder."""

from __future__ import annotations

import os
import time
from pathlib import Path

from stslam import experiments
from stslam.errors import ConfigError
from stslam.config.readers import get_int, lookup
from stslam.io.results import write_run

# Distributions whose versions every results folder records (version.json, SPEC 12).
TRACKED_PACKAGES = (
    "numpy", "scipy", "pandas", "matplotlib", "filterpy", "hydra-core", "omegaconf",
    "mcap", "mcap-protobuf-support", "foxglove-schemas-protobuf", "protobuf",
    "opencv-python-headless", "evo",
)


def execute(config: dict, argv: list[str] | None = None) -> Path:
    """Run ``config["exp_name"]`` and write ``<out_dir>/<exp>/<stamp>-<sha>/``.

    The configuration is checked by the experiment before any work starts and
    nothing is written unless the run completes (SPEC 12).
    """
    name = lookup(config, "exp_name", None)
    if name is None:
        raise ConfigError(
            "exp: no experiment chosen; add +exp=<name> with one of " + ", ".join(experiments.EXPERIMENTS + experiments.USER_INPUT_RUNS))
    module = experiments.load(name)
    get_int(config, "seed", low=0)
    get_int(config, "n_seeds", low=1)
    out_dir = _writable_out_dir(config, name)
    started = time.monotonic()
    output = module.run(config)
    try:
        folder = write_run(out_dir, name, config, output, seed=config["seed"], argv=argv,
                           packages=TRACKED_PACKAGES, duration_s=time.monotonic() - started)
    except OSError as error:  # disk full, permissions changed during the run …
        raise ConfigError(f"out_dir: cannot write the results folder under {out_dir / name}: "
                          f"{error.strerror or error}") from None
    finally:
        _close_figures(output.figures)
    for line in output.lines:
        print(line)
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


def _close_figures(figures) -> None:
    import matplotlib.pyplot as plt

    for figure in figures.values():
        plt.close(figure)
