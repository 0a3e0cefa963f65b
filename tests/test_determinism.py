"""Determinism (SPEC 11, SPEC 12): the same config and seed give byte-identical
``metrics.csv`` in two separate processes; another seed gives other numbers.

Each experiment is run cut down; add an experiment with one line in
``CUT_DOWN_OVERRIDES`` (experiment name → overrides).
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from stslam.results import complete_runs

REPO = Path(__file__).resolve().parent.parent
CUT_DOWN_OVERRIDES = {
    "structure_fit": ["n_seeds=20", "sweep.n_seeds=0"],
    "temporal_order": ["n_seeds=3"],
}
SEED = 11


def _start(exp: str, overrides: list[str], out_dir: Path, seed: int) -> subprocess.Popen:
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.Popen([sys.executable, str(REPO / "experiments" / "run.py"), f"+exp={exp}", *overrides,
                             f"seed={seed}", "progress=false", f"out_dir={out_dir}"],
                            cwd=REPO, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _metrics_bytes(process: subprocess.Popen, out_dir: Path, exp: str) -> bytes:
    _, stderr = process.communicate(timeout=300)
    assert process.returncode == 0, stderr
    (folder,) = complete_runs(out_dir, exp)
    return (folder / "metrics.csv").read_bytes()


@pytest.mark.parametrize("exp", sorted(CUT_DOWN_OVERRIDES))
def test_same_seed_same_bytes_in_two_processes(exp, tmp_path):
    overrides = CUT_DOWN_OVERRIDES[exp]
    # Two processes at once (one per core); each its own out_dir so each has exactly one folder.
    runs = {name: (tmp_path / name, _start(exp, overrides, tmp_path / name, seed))
            for name, seed in (("first", SEED), ("second", SEED))}
    first, second = (_metrics_bytes(process, out_dir, exp) for out_dir, process in runs.values())
    assert first == second

    other_dir = tmp_path / "other"
    other = _metrics_bytes(_start(exp, overrides, other_dir, SEED + 1000), other_dir, exp)
    # The seed column differs anyway; the test must see other *numbers* to be able to fail.
    values = pd.read_csv(complete_runs(tmp_path / "first", exp)[0] / "metrics.csv").drop(columns="seed")
    other_values = pd.read_csv(complete_runs(other_dir, exp)[0] / "metrics.csv").drop(columns="seed")
    assert other != first
    assert list(values.columns) == list(other_values.columns)
    numeric = values.select_dtypes("number").columns
    assert not values[numeric].equals(other_values[numeric])
