"""Which seeds of a SLAM run get a ``scene.mcap`` (SPEC 15): the ``scene`` block of an experiment config."""

from __future__ import annotations

from stslam.config.readers import lookup
from stslam.errors import ConfigError

DEFAULT_SEEDS = (0,)


def scene_seed_indices(cfg, n_seeds: int) -> list[int]:
    """Indices (0 … n_seeds−1, as ``plot_seed``) of the seeds whose scene is written; [] writes none.

    ``scene.seeds`` defaults to [0], the first seed of the run.
    """
    value = lookup(cfg, "scene.seeds", list(DEFAULT_SEEDS))
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)):
        raise ConfigError(f"scene.seeds: expected a list of seed indices in 0 … {n_seeds - 1}, got {value!r}")
    out = []
    for i, k in enumerate(value):
        if isinstance(k, bool) or not isinstance(k, int) or not 0 <= k < n_seeds:
            raise ConfigError(f"scene.seeds[{i}]: expected a seed index in 0 … {n_seeds - 1}, got {k!r}")
        if k not in out:
            out.append(k)
    return sorted(out)
