"""Run one experiment: ``python experiments/run.py +exp=<name> [overrides]``.

Only the Hydra entry point lives here; the work is ``stslam.runner.execute``.
``tracks=<glob>`` is accepted as a short form of ``tracks.glob=<glob>``.
"""

from __future__ import annotations

import sys

import hydra
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from stslam.errors import StslamError
from stslam.runner import execute

SHORT_FORMS = {"tracks": "tracks.glob"}


def _expand_short_forms(argv: list[str]) -> list[str]:
    out = []
    for arg in argv:
        key, sep, value = arg.partition("=")
        out.append(f"{SHORT_FORMS[key]}={value}" if sep and key in SHORT_FORMS else arg)
    return out


@hydra.main(version_base="1.3", config_path="../conf", config_name="config")
def main(cfg: DictConfig) -> None:
    try:
        config = OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)
        execute(config, argv=sys.argv)
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
    main()
