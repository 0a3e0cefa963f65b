"""What an experiment hands back to be written as a results folder (SPEC 12)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd


@dataclass
class ExperimentOutput:
    """Everything an experiment produced, held in memory until it is written.

    Attributes
    ----------
    metrics : pandas.DataFrame
        One row per seed and method: columns ``seed, method, <metrics…>``.
    figures : dict[str, matplotlib.figure.Figure]
        Figure name (no extension) to figure; written as PDF and PNG.
    trajectories : dict[str, numpy.ndarray]
        TUM file name (``<method>_seed<k>.tum``) to an array of shape (n, 8):
        ``t x y z qx qy qz qw``.
    tables : dict[str, pandas.DataFrame]
        Further CSV tables (file name without extension to table).
    files : dict[str, str]
        Further text files (relative path to content).
    binaries : dict[str, bytes]
        Further binary files (relative path to content), e.g. ``scene.mcap``.
    lines : list[str]
        A short human-readable summary printed when the run finishes.
    summary_extra : pandas.DataFrame, optional
        Rows appended to ``summary.csv`` (same columns, ``stslam.eval.stats.SUMMARY_COLUMNS``)
        for statistics that are not a mean over seeds, e.g. an RMSE over seeds.
    """

    metrics: pd.DataFrame
    figures: dict[str, Any] = field(default_factory=dict)
    trajectories: dict[str, np.ndarray] = field(default_factory=dict)
    tables: dict[str, pd.DataFrame] = field(default_factory=dict)
    files: dict[str, str] = field(default_factory=dict)
    binaries: dict[str, bytes] = field(default_factory=dict)
    lines: list[str] = field(default_factory=list)
    summary_extra: pd.DataFrame | None = None
