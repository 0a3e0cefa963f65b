"""Experiments, one module per paper section (SPEC 8, SPEC 12).

Each module ``stslam.experiments.<name>`` exposes ``run(cfg: dict) ->
ExperimentOutput``: it validates its configuration first (raising
:class:`~stslam.errors.ConfigError` naming the parameter), computes everything
in memory and returns it; :mod:`stslam.io.results` writes the folder. Those in
:data:`MULTI_SEED` take ``run(cfg, seeds=None)``: their seeds go through
``seeds.map`` (:class:`stslam.experiments.seeds.SeedRunner`; None: one after
another, nothing kept).
"""

from __future__ import annotations

import importlib

from stslam.errors import ConfigError

EXPERIMENTS = (
    "structure_fit",
    "temporal_order",
    "articulation_estimation",
    "dynamic_slam",
    "fridge",
    "classify_tracks",
)
# Experiments whose seeds are units of work (jobs=, resume=true; SPEC 12, 18)
MULTI_SEED = ("structure_fit", "temporal_order", "articulation_estimation", "dynamic_slam", "fridge")
# Runs on a user's own input files, not part of the paper's reproduction plan (experiments/reproduce.py).
USER_INPUT_RUNS = ("marker_video",)


def load(name):
    """The experiment module called ``name``; ConfigError for unknown names."""
    if name not in EXPERIMENTS + USER_INPUT_RUNS:
        raise ConfigError(f"exp: expected one of {', '.join(EXPERIMENTS + USER_INPUT_RUNS)}; got {name!r}")
    try:
        return importlib.import_module(f"stslam.experiments.{name}")
    except ModuleNotFoundError as error:
        if error.name == f"stslam.experiments.{name}":
            raise ConfigError(f"exp: experiment {name!r} is not implemented in this version") from None
        raise
