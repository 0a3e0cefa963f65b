"""Run one experiment: ``python experiments/run.py +exp=<name> [overrides]``.

Only the Hydra entry point lives here; the work is ``stslam.runner.execute``.
``tracks=<glob>`` is accepted as a short form of ``tracks.glob=<glob>``.
"""

from __future__ import annotations

import sys
from pathlib import Path

import hydra
from hydra import compose, initialize_config_dir
from hydra.core.hydra_config import HydraConfig
from hydra.errors import MissingConfigException
from hydra.types import RunMode
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from stslam.errors import StslamError
from stslam.runner import execute

SHORT_FORMS = {"tracks": "tracks.glob"}
CONF_DIR = Path(__file__).resolve().parent.parent / "conf"


def _expand_short_forms(argv: list[str]) -> list[str]:
    out = []
    for arg in argv:
        key, sep, value = arg.partition("=")
        out.append(f"{SHORT_FORMS[key]}={value}" if sep and key in SHORT_FORMS else arg)
    return out


def _one_line(error: Exception) -> str:
    """Hydra's multi-line composition errors as one line naming the key or group."""
    if isinstance(error, MissingConfigException) and getattr(error, "missing_cfg_file", None):
        group, _, option = error.missing_cfg_file.rpartition("/")
        options = sorted(p.stem for p in (CONF_DIR / group).glob("*.yaml")) if group else []
        expected = f"; expected one of {', '.join(options)}" if options else ""
        return f"{group or 'config'}: no config named {option!r}{expected}"
    lines = [line.strip() for line in str(error).splitlines()]
    lines = [line for line in lines if line and not line.startswith(("See https", "Config search path"))
             and not line.startswith("provider=")]
    if error.__cause__ is not None:
        lines.append(str(error.__cause__).splitlines()[0])
    return "; ".join(lines)


def _check_overrides(overrides: list[str]) -> None:
    """Compose the config once (single runs only) so a bad override fails in one line."""
    try:
        with initialize_config_dir(config_dir=str(CONF_DIR), version_base="1.3"):
            compose("config", overrides=[o for o in overrides if not o.startswith(("hydra.", "hydra/"))])
    except Exception as error:  # noqa: BLE001 - every composition error is reported the same way
        print(f"error: {_one_line(error)}", file=sys.stderr)
        sys.exit(2)


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
def main(cfg: DictConfig) -> None:
    try:
        config = OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)
        folder = execute(config, argv=sys.argv)
        _record_sweep_job(folder)
    except OmegaConfBaseException as error:
        key = getattr(error, "full_key", None) or ""
        print(f"error: {key + ': ' if key else ''}{str(error).splitlines()[0]}", file=sys.stderr)
        sys.exit(2)
    except StslamError as error:
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("interrupted: no results folder was written", file=sys.stderr)
        sys.exit(130)


if __name__ == "__main__":
    sys.argv = _expand_short_forms(sys.argv)
    if not any(arg.startswith("-") for arg in sys.argv[1:]):  # Hydra flags (-m, --cfg …) skip it
        _check_overrides(sys.argv[1:])
    main()
