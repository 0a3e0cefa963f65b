"""Run one experiment: ``python experiments/run.py +exp=<name> [overrides]``.

Only the Hydra entry point lives here; the work is ``stslam.experiments.runner.execute``.
``tracks=<glob>`` is accepted as a short form of ``tracks.glob=<glob>``.
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

import hydra
from hydra import compose, initialize_config_dir
from hydra.core.hydra_config import HydraConfig
from hydra.core.override_parser.overrides_parser import OverridesParser
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf

from stslam.errors import ConfigError
from stslam.experiments.cli import main_guard, one_line

SHORT_FORMS = {"tracks": "tracks.glob"}
MULTIRUN_FLAGS = {"-m", "--multirun"}
CONF_DIR = Path(__file__).resolve().parent.parent / "conf"
INTERRUPTED = "no results folder was written"


def _expand_short_forms(argv: list[str]) -> list[str]:
    out = []
    for arg in argv:
        key, sep, value = arg.partition("=")
        out.append(f"{SHORT_FORMS[key]}={value}" if sep and key in SHORT_FORMS else arg)
    return out


def _single_runs(overrides: list[str], multirun: bool) -> list[list[str]]:
    """Override lists to compose so that every value of every override is composed once.

    A single run is one list. A multirun (``-m``) sweep ``key=a,b,c`` gives one list
    per value, the other overrides at their first value (linear, not the full
    product): enough to catch an unknown key or group option in any job.
    """
    parsed = OverridesParser.create().parse_overrides(overrides)
    choices = []
    for override in parsed:
        key = override.get_key_element()
        if not override.key_or_group:
            raise ConfigError(f"override {override.input_line!r}: expected key=value with a key before '='")
        if override.is_sweep_override() and not multirun:
            value = override.input_line.partition("=")[2]
            raise ConfigError(f"{key.lstrip('+~')}: {value!r} is a sweep of several values; add -m to run "
                              "one job per value (a list is written [a,b], a string with commas is quoted)")
        if override.is_sweep_override() and override.is_discrete_sweep():
            choices.append([f"{key}={value}" for value in override.sweep_string_iterator()])
        else:
            choices.append([override.input_line])
    first = [values[0] for values in choices]
    runs = [first]
    for i, values in enumerate(choices):
        runs.extend(first[:i] + [value] + first[i + 1:] for value in values[1:])
    return runs


def _check_overrides(overrides: list[str], multirun: bool = False) -> None:
    """Compose the config before Hydra starts so that a bad override, or a value the experiment needs and
    was not given (``???`` in its config), fails in one line; the missing values are named together.

    Values an experiment checks itself (SPEC 12) fail later, in its job.
    """
    try:
        runs = _single_runs(overrides, multirun)
        with warnings.catch_warnings(), initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            warnings.simplefilter("ignore")  # Hydra warns again when it composes for real
            missing = []
            for run in runs:
                missing += [key for key in sorted(OmegaConf.missing_keys(compose("config", overrides=run)))
                            if key not in missing]
    except Exception as error:  # noqa: BLE001 - every composition error is reported the same way
        raise ConfigError(one_line(error, CONF_DIR)) from None
    if missing:
        raise ConfigError(f"{', '.join(missing)}: not set; give each on the command line, e.g. {missing[0]}=<value>")


def _record_sweep_job(folder: Path) -> None:
    """In a multirun, leave the job's overrides and results folder in its sweep sub-folder.

    ``experiments/aggregate.py <sweep dir>`` reads these to merge a sweep.
    """
    hydra_cfg = HydraConfig.get()
    if hydra_cfg.mode != RunMode.MULTIRUN:
        return
    job_dir = Path(hydra_cfg.runtime.output_dir)
    job_dir.mkdir(parents=True, exist_ok=True)
    (job_dir / "job.yaml").write_text(OmegaConf.to_yaml(OmegaConf.create({
        "results_folder": str(folder.resolve()),
        "overrides": list(hydra_cfg.overrides.task),
    })))


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
@main_guard(INTERRUPTED)
def main(cfg: DictConfig) -> None:
    from stslam.experiments.runner import execute  # here, not at the top: a bad override fails without importing scipy

    config = OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)
    folder = execute(config, argv=sys.argv, in_sweep=HydraConfig.get().mode == RunMode.MULTIRUN)
    _record_sweep_job(folder)


@main_guard(INTERRUPTED, CONF_DIR)
def cli() -> None:
    """Check the overrides (one line for a bad one), then let Hydra run the job or the sweep."""
    sys.argv = _expand_short_forms(sys.argv)
    # Hydra's parser takes flags only before the overrides: move -m/--multirun there.
    sys.argv = ([sys.argv[0]] + [arg for arg in sys.argv[1:] if arg in MULTIRUN_FLAGS]
                + [arg for arg in sys.argv[1:] if arg not in MULTIRUN_FLAGS])
    flags = {arg for arg in sys.argv[1:] if arg.startswith("-")}
    if flags <= MULTIRUN_FLAGS:  # other Hydra flags (--cfg, --help …) skip the check
        _check_overrides([arg for arg in sys.argv[1:] if arg not in flags], multirun=bool(flags))
    main()


if __name__ == "__main__":
    cli()
