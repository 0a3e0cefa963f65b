"""Shared test helpers: compose experiment configs with Hydra's compose API."""

from __future__ import annotations

import os
from pathlib import Path

import stslam  # noqa: F401  (first: sets single-threaded BLAS before numpy loads; see stslam/__init__)
import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

REPO = Path(__file__).resolve().parent.parent
CONF = REPO / "conf"

os.environ.setdefault("MPLBACKEND", "Agg")


def compose_config(exp: str, overrides=(), out_dir=None) -> dict:
    """Resolved config of ``+exp=<exp>`` with ``overrides``, as a plain dict."""
    extra = [f"out_dir={out_dir}"] if out_dir is not None else []
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("config", overrides=[f"+exp={exp}", "progress=false", *extra, *overrides])
    return OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)


@pytest.fixture
def compose_exp(tmp_path):
    """Compose an experiment config whose results go under ``tmp_path``."""

    def _compose(exp: str, *overrides: str) -> dict:
        return compose_config(exp, overrides, out_dir=tmp_path / "results")

    return _compose
