"""Merging sweep jobs (stslam.eval.sweep) and the aggregate command on hand-made job folders."""

from __future__ import annotations

import subprocess
import sys

import pandas as pd
import pytest
import yaml

from stslam.output import ExperimentOutput
from stslam.io.results import write_run
from stslam.eval.sweep import merge_jobs, parse_overrides, summarise_sweep, swept_keys

from conftest import REPO


def test_parse_overrides_drops_prefixes():
    assert parse_overrides(["+exp=dynamic_slam", "seed=3", "sensor.sigma=0.1", "flag"]) == {
        "exp": "dynamic_slam", "seed": "3", "sensor.sigma": "0.1"}


def test_seed_is_not_a_swept_key_but_other_varying_keys_are():
    jobs = [{"exp": "x", "seed": "0", "tau": "0.6"}, {"exp": "x", "seed": "1", "tau": "0.8"}]
    assert swept_keys(jobs) == ["tau"]


def test_summary_per_swept_value():
    jobs = [{"tau": "0.6", "seed": "0"}, {"tau": "0.8", "seed": "1"}]
    tables = [pd.DataFrame({"seed": [0, 0], "method": ["a", "b"], "ate_m": [1.0, 2.0]}),
              pd.DataFrame({"seed": [1, 1], "method": ["a", "b"], "ate_m": [3.0, 4.0]})]
    merged, keys = merge_jobs(jobs, tables)
    assert keys == ["tau"] and list(merged.columns[:3]) == ["tau", "seed", "method"]
    summary = summarise_sweep(merged, keys)
    # one block per tau value, one row per method: the means are the single values
    assert summary[["tau", "method", "mean"]].values.tolist() == [
        ["0.6", "a", 1.0], ["0.6", "b", 2.0], ["0.8", "a", 3.0], ["0.8", "b", 4.0]]


def test_aggregate_command_merges_seed_jobs(tmp_path):
    sweep = tmp_path / "multirun" / "stamp"
    for job in range(4):
        metrics = pd.DataFrame({"seed": [job], "method": ["a"], "ate_m": [float(job)]})
        folder = write_run(tmp_path / "results", "demo", {"exp_name": "demo", "seed": job},
                           ExperimentOutput(metrics=metrics), seed=job)
        (sweep / str(job)).mkdir(parents=True)
        (sweep / str(job) / "job.yaml").write_text(yaml.safe_dump(
            {"results_folder": str(folder), "overrides": ["+exp=demo", f"seed={job}"]}))
    done = subprocess.run([sys.executable, str(REPO / "experiments" / "aggregate.py"), str(sweep),
                           "--out-dir", str(tmp_path / "results")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    out = next((tmp_path / "results" / "demo_sweep").iterdir())
    summary = pd.read_csv(out / "summary.csv")
    # four jobs, values 0..3: mean 1.5 over n = 4
    assert summary.loc[0, "mean"] == pytest.approx(1.5) and summary.loc[0, "n"] == 4


def test_aggregate_rejects_a_folder_without_jobs(tmp_path):
    done = subprocess.run([sys.executable, str(REPO / "experiments" / "aggregate.py"), str(tmp_path)],
                          capture_output=True, text=True)
    assert done.returncode == 2
    assert done.stderr.strip().count("\n") == 0 and "no */job.yaml" in done.stderr


@pytest.mark.parametrize("launcher", ["joblib", "submitit_local"])
def test_multirun_with_launcher_then_aggregate(tmp_path, launcher):
    """The documented sweep path end to end: two seed jobs through a launcher, then one summary."""
    out = tmp_path / "results"
    run = subprocess.run(
        [sys.executable, str(REPO / "experiments" / "run.py"), "-m", "+exp=structure_fit", "seed=0,1",
         "n_seeds=3", "sweep.n_seeds=0", f"out_dir={out}", "progress=false", f"hydra/launcher={launcher}"],
        capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    sweeps = list((out / "multirun").iterdir())
    assert len(sweeps) == 1 and len(list(sweeps[0].glob("*/job.yaml"))) == 2
    done = subprocess.run([sys.executable, str(REPO / "experiments" / "aggregate.py"), str(sweeps[0]),
                           "--out-dir", str(out)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    merged = pd.read_csv(next((out / "structure_fit_sweep").iterdir()) / "metrics.csv")
    # two jobs × 3 Monte Carlo runs: seeds 0–2 from job seed=0 and 1–3 from job seed=1
    separate = merged[merged["method"] == "separate"]
    assert len(separate) == 6 and sorted(separate["seed"]) == [0, 1, 1, 2, 2, 3]
