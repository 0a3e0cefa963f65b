"""Run one experiment from a resolved configuration and write its results folder."""

from __future__ import annotations

from pathlib import Path

from stslam import experiments
from stslam.params import get_int, lookup
from stslam.results import write_run


def execute(config: dict, argv: list[str] | None = None) -> Path:
    """Run ``config["exp_name"]`` and write ``<out_dir>/<exp>/<stamp>-<sha>/``.

    The configuration is checked by the experiment before any work starts and
    nothing is written unless the run completes (SPEC 12).
    """
    name = lookup(config, "exp_name", None)
    if name is None:
        raise experiments.ConfigError(
            "exp: no experiment chosen; add +exp=<name> with one of " + ", ".join(experiments.EXPERIMENTS))
    module = experiments.load(name)
    get_int(config, "seed", low=0)
    get_int(config, "n_seeds", low=1)
    out_dir = lookup(config, "out_dir")
    output = module.run(config)
    try:
        folder = write_run(out_dir, name, config, output, seed=config["seed"], argv=argv)
    finally:
        _close_figures(output.figures)
    for line in output.lines:
        print(line)
    print(f"results: {folder}")
    return folder


def _close_figures(figures) -> None:
    import matplotlib.pyplot as plt

    for figure in figures.values():
        plt.close(figure)
