"""Convert a ROS bag to the SPEC 9 MCAP: ``python experiments/convert.py bag=<path> out=<file.mcap> [overwrite=true]``.

Only the Hydra entry point lives here; settings are read by ``stslam.config.convert``,
the work is ``stslam.io.bag_convert.convert_bag`` (SPEC 15).
"""

from __future__ import annotations

import sys

import hydra
from omegaconf import DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from stslam.config.convert import convert_from_config
from stslam.errors import StslamError
from stslam.io.bag_convert import convert_bag


@hydra.main(version_base="1.3", config_path="../conf", config_name="convert")
def main(cfg: DictConfig) -> None:
    try:
        report = convert_bag(convert_from_config(OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)))
    except OmegaConfBaseException as error:
        key = getattr(error, "full_key", None) or ""
        print(f"error: {key + ': ' if key else ''}{str(error).splitlines()[0]}", file=sys.stderr)
        sys.exit(2)
    except StslamError as error:
        print(f"error: {error}", file=sys.stderr)
        sys.exit(2)
    except KeyboardInterrupt:
        print("interrupted: no output file was written", file=sys.stderr)
        sys.exit(130)
    for line in report.lines():
        print(line)


if __name__ == "__main__":
    main()
