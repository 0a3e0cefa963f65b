"""Results folders (SPEC 12) and summary statistics."""

from __future__ import annotations

import datetime as dt
import json

import numpy as np
import pandas as pd
import pytest
from matplotlib.figure import Figure

from stslam.output import ExperimentOutput
from stslam.io.results import complete_runs, write_run
from stslam.eval.stats import mean_ci, summarise


def _output():
    metrics = pd.DataFrame({"seed": [0, 1, 0, 1], "method": ["a", "a", "b", "b"],
                            "ate_m": [1.0, 3.0, 2.0, 2.0]})
    fig = Figure()
    fig.add_subplot().plot([0, 1], [0, 1])
    traj = np.zeros((2, 8))
    traj[:, 7] = 1.0
    return ExperimentOutput(metrics=metrics, figures={"line": fig},
                            trajectories={"a_seed0.tum": traj})


def test_mean_ci_matches_closed_form():
    # samples 1, 3: mean 2, s = sqrt(2), t_{0.975,1} = 12.706204736...
    mean, low, high = mean_ci([1.0, 3.0])
    half = 12.706204736174707 * np.sqrt(2) / np.sqrt(2)
    assert mean == 2.0
    assert low == pytest.approx(2.0 - half, rel=1e-12)
    assert high == pytest.approx(2.0 + half, rel=1e-12)


def test_summary_has_one_row_per_method_and_metric():
    summary = summarise(_output().metrics)
    assert list(summary.columns) == ["method", "metric", "mean", "median", "ci_low", "ci_high", "n"]
    assert summary[["method", "metric"]].values.tolist() == [["a", "ate_m"], ["b", "ate_m"]]
    assert summary["mean"].tolist() == [2.0, 2.0]
    # method b has zero spread: its interval collapses onto the mean
    assert summary.iloc[1][["ci_low", "ci_high"]].tolist() == [2.0, 2.0]


def test_run_folder_is_complete_and_never_reused(tmp_path):
    now = dt.datetime(2026, 1, 2, 3, 4, 5)
    first = write_run(tmp_path, "demo", {"seed": 0}, _output(), seed=0, argv=["x"], now=now)
    second = write_run(tmp_path, "demo", {"seed": 0}, _output(), seed=0, argv=["x"], now=now)
    assert first != second
    assert second.name == first.name + "-1"
    for folder in (first, second):
        names = {p.name for p in folder.iterdir()}
        assert {"config.yaml", "version.json", "metrics.csv", "summary.csv", "figures",
                "trajectories"} <= names
        assert {p.name for p in (folder / "figures").iterdir()} == {"line.pdf", "line.png"}
        assert json.loads((folder / "version.json").read_text())["seed"] == 0
    assert (first / "metrics.csv").read_bytes() == (second / "metrics.csv").read_bytes()
    assert complete_runs(tmp_path, "demo") == [first, second]


def test_failed_write_leaves_no_folder(tmp_path):
    output = _output()
    output.tables = {"bad": "not a table"}  # to_csv fails mid-write
    with pytest.raises(AttributeError):
        write_run(tmp_path, "demo", {"seed": 0}, output, seed=0)
    assert list((tmp_path / "demo").iterdir()) == []
