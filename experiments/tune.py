"""Tune the SLAM filters' process noises for one world and write ``conf/tuning/<world>.yaml``.

    python experiments/tune.py world=<name> [methods=[ekf_slam,oracle]] [seed=1000] [n_seeds=20] [...]

Arguments are Hydra overrides of ``+exp=dynamic_slam`` (world, sensor,
robot.control_noise, fixed filter settings). Tuning seeds default to
1000–1019, disjoint from the evaluation seeds 0–49. Every tuned parameter is
scanned on the same grid (``stslam.slam.tuning.DEFAULT_GRID``); the best
setting by mean ATE is written, with the command and the runner-up settings
as comments. Methods not tuned keep their values in the file. A fixed setting
of a tuned method given on the command line (``filters.oracle.order=0``) is
written into its block beside the tuned values, so that the file holds the
settings the values were tuned for.
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from stslam.config.readers import get_bool, get_int, lookup
from stslam.config.robot import sensor_from_config
from stslam.config.sim import world_from_config
from stslam.config.slam import filter_params_from_config, motion_noise_order_from_config, update_iterations_from_config
from stslam.experiments.cli import main_guard
from stslam.experiments.dynamic_slam import check_methods
from stslam.slam.tuning import DEFAULT_GRID, TUNED_PARAMETERS, grid_search

CONF = Path(__file__).resolve().parent.parent / "conf"


def _format(value: float) -> str:
    return repr(float(value))


def previous_blocks(text: str) -> dict[str, list[str]]:
    """Method → its lines in an existing tuning file (the comment lines above ``  <method>: {…}`` and that line)."""
    blocks, pending = {}, []
    for line in text.splitlines():
        if line.startswith("  #"):
            pending.append(line)
        elif line.startswith("  ") and ":" in line:
            blocks[line.strip().split(":", 1)[0]] = [*pending, line]
            pending = []
        else:
            pending = []
    return blocks


def fixed_settings(argv, methods) -> dict[str, dict[str, str]]:
    """Method → {key: value} of the command-line overrides ``filters.<method>.<key>=<value>`` of ``methods``
    that are not tuned parameters (values as typed)."""
    fixed: dict[str, dict[str, str]] = {}
    for arg in argv:
        name, sep, value = arg.partition("=")
        parts = name.lstrip("+").split(".")
        if sep and len(parts) == 3 and parts[0] == "filters" and parts[1] in methods \
                and parts[2] not in TUNED_PARAMETERS.get(parts[1], ()):
            fixed.setdefault(parts[1], {})[parts[2]] = value
    return fixed


def tuning_yaml(world_name: str, command: str, seeds, tables: dict, previous_text: str,
                fixed: dict | None = None) -> str:
    """Text of ``conf/tuning/<world>.yaml``: header comments, then ``filters:`` with the best settings.

    Each method's block names the command that tuned it and holds its
    ``fixed`` settings (method → {key: value}, :func:`fixed_settings`) before
    the tuned values; methods not tuned now keep their block from
    ``previous_text`` verbatim.
    """
    fixed = fixed or {}
    previous = previous_blocks(previous_text)
    lines = ["# @package _global_",
             f"# Process noises of the SLAM filters for world {world_name}, tuned by grid search",
             f"# (grid {list(DEFAULT_GRID)} per parameter, full product) for mean ATE over",
             f"# tuning seeds {seeds[0]}–{seeds[-1]} (evaluation seeds are 0–49). Each block names",
             "# the command that regenerates it.",
             "filters:"]
    for method in TUNED_PARAMETERS:
        if method in tables:
            table = tables[method]
            best = table.iloc[0]
            values = ", ".join([*(f"{k}: {v}" for k, v in fixed.get(method, {}).items()),
                                *(f"{p}: {_format(best[p])}" for p in TUNED_PARAMETERS[method])])
            lines.append(f"  # {command}")
            lines.append(f"  # {method}: mean ATE {best['mean_ate_m']:.4f} m at the best setting; next best:")
            for _, row in table.iloc[1:4].iterrows():
                lines.append("  #   " + ", ".join(f"{p}={row[p]:g}" for p in TUNED_PARAMETERS[method])
                             + f": {row['mean_ate_m']:.4f} m")
            lines.append(f"  {method}: {{{values}}}")
        elif method in previous:
            lines.extend(previous[method])
    return "\n".join(lines) + "\n"


@main_guard("no tuning file was written", CONF)
def main(argv: list[str]) -> int:
    overrides = ["+exp=dynamic_slam", "seed=1000", "n_seeds=20", "progress=true", *argv]
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = OmegaConf.to_container(compose("config", overrides=overrides), resolve=True, throw_on_missing=True)
    seed = get_int(cfg, "seed", low=0)
    seeds = list(range(seed, seed + get_int(cfg, "n_seeds", low=1)))
    methods = check_methods(cfg)
    control_noise = get_bool(cfg, "robot.control_noise")
    world = world_from_config(cfg)
    sensor = sensor_from_config(cfg)
    order, iterations = motion_noise_order_from_config(cfg), update_iterations_from_config(cfg)
    tables = {m: grid_search(filter_params_from_config(cfg, m), m, world, sensor, control_noise, seeds,
                             motion_order=order, iterations=iterations,
                             show_progress=bool(lookup(cfg, "progress", False)))
              for m in methods if m in TUNED_PARAMETERS}
    world_choice = world.name
    target = CONF / "tuning" / f"{world_choice}.yaml"
    previous = target.read_text() if target.is_file() else ""
    command = "python experiments/tune.py " + " ".join(shlex.quote(a) for a in argv)
    target.write_text(tuning_yaml(world_choice, command.strip(), seeds, tables, previous,
                                  fixed_settings(argv, tables)))
    for method, table in tables.items():
        print(f"{method}: best {table.iloc[0].to_dict()}")
    print(f"wrote {target}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
