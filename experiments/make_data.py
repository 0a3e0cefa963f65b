"""Generate a data set: ``python experiments/make_data.py +data=fridge [seed=…] [out=…] [overwrite=true]``.

Only the Hydra entry point lives here; the work is ``stslam.io.datasets.generate``.
"""

from __future__ import annotations

import sys

import hydra
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from stslam.config.rgbd import data_request_from_config
from stslam.io.datasets import generate
from stslam.errors import StslamError


@hydra.main(version_base="1.3", config_path="../conf", config_name="make_data")
def main(cfg: DictConfig) -> None:
    try:
        report = generate(data_request_from_config(OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)))
    except OmegaConfBaseException as error:
        key = getattr(error, "full_key", None) or ""
        print(f"error: {key + ': ' if key else ''}{str(error).splitlines()[0]}", file=sys.stderr)
        sys.exit(2)
    except StslamError as error:
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("interrupted: no data file was written", file=sys.stderr)
        sys.exit(130)
    for line in report.lines():
        print(line)


if __name__ == "__main__":
    main()
