"""Generate a data set: ``python experiments/make_data.py +data=fridge [seed=…] [out=…] [overwrite=true]``.

Only the Hydra entry point lives here; the work is ``stslam.experiments.datasets.generate``.
"""

from __future__ import annotations

import hydra
from omegaconf import DictConfig, OmegaConf

from stslam.config.rgbd import data_request_from_config
from stslam.experiments.cli import main_guard
from stslam.experiments.datasets import generate


@hydra.main(version_base="1.3", config_path="../conf", config_name="make_data")
@main_guard("no data file was written")
def main(cfg: DictConfig) -> None:
    report = generate(data_request_from_config(OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)))
    for line in report.lines():
        print(line)


if __name__ == "__main__":
    main()
