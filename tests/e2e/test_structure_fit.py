"""Smoke tests of the structure_fit experiment (SPEC 8.1, SPEC 12), cut down to 60 seeds.

Reference values come from 2000-seed runs (seeds 0–1999) of the same code:
``python experiments/run.py +exp=structure_fit n_seeds=2000 sweep.n_seeds=0`` and the
same with ``protocol=fair arc_deg=180 n_samples=20``.
"""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from stslam.articulation.crb import crb_circle_nuisance_angles
from stslam.errors import ConfigError
from stslam.experiments import structure_fit
from stslam.experiments.runner import execute
from conftest import REPO, compose_config

N = 60
CUT = ("n_seeds=60", "sweep.n_seeds=10", "sweep.arcs_deg=[180]", "sweep.n_samples=[10]")

# Paper protocol, 2000 seeds: population quantiles q(0.24), q(0.76) of the per-seed errors.
# The median of 60 draws lies between q(0.5 − 4·0.5/√60) = q(0.24) and q(0.76) unless a
# binomial count is 4 SE off (probability < 1e-4): a distribution-free tolerance, needed
# because the joint fit's errors are heavy-tailed (4 of 2000 runs exceed 1 km).
PAPER_MEDIAN_BANDS = {
    ("joint", "centre_error"): (0.164, 0.4378),
    ("joint", "radius_error"): (0.0774, 0.3248),
    ("separate", "centre_error"): (0.0447, 0.108),
    ("separate", "radius_error"): (0.0152, 0.0545),
}
FAIR_RATIO_2000 = 0.074832 / 0.073899  # separate / crb centre RMSE, 180°, n = 20, 2000 runs


@pytest.fixture(scope="module")
def paper_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("sf")
    cfg = compose_config("structure_fit", CUT, out_dir=out / "results")
    return out, cfg, execute(cfg)


def test_results_folder_follows_spec12(paper_run):
    _, _, folder = paper_run
    names = {p.name for p in folder.iterdir()}
    assert {"config.yaml", "version.json", "metrics.csv", "summary.csv", "figures",
            "table1.csv", "rmse.csv", "sweep.csv"} <= names
    assert {p.name for p in (folder / "figures").iterdir()} == {
        "single_run.pdf", "single_run.png", "sweep.pdf", "sweep.png"}
    metrics = pd.read_csv(folder / "metrics.csv")
    assert list(metrics.columns) == ["seed", "method", "centre_error", "radius_error"]
    assert len(metrics) == 3 * N and set(metrics["method"]) == {"joint", "separate", "crb"}
    assert sorted(metrics["seed"].unique()) == list(range(N))
    summary = pd.read_csv(folder / "summary.csv")
    assert list(summary.columns) == ["method", "metric", "mean", "median", "ci_low", "ci_high", "n"]
    sweep = pd.read_csv(folder / "sweep.csv")
    assert len(sweep) == 2 * 4  # (one arc + one count) × (separate, joint, crb, crb_joint)
    assert np.allclose(sweep.loc[sweep["method"] == "crb", "centre_ratio_to_crb"], 1.0)


def test_paper_protocol_values_within_monte_carlo_tolerance(paper_run):
    _, _, folder = paper_run
    metrics = pd.read_csv(folder / "metrics.csv")
    for (method, metric), (low, high) in PAPER_MEDIAN_BANDS.items():
        median = metrics.loc[metrics["method"] == method, metric].median()
        assert low <= median <= high, (method, metric, median)
    # the efficient-estimator mean of the separate fit, from the CRB: its 60-seed mean must
    # sit within 4 standard errors (sample std / √60) — the fit is efficient here (the
    # 2000-seed mean 0.0805 equals the CRB value 0.0805 to 3 digits).
    sep = metrics.loc[metrics["method"] == "separate", "centre_error"]
    crb_mean = metrics.loc[metrics["method"] == "crb", "centre_error"].iloc[0]
    assert abs(sep.mean() - crb_mean) < 4 * sep.std(ddof=1) / np.sqrt(N)
    # the paper's finding: the joint fit (4 samples, misspecified rate) is far worse
    joint = metrics.loc[metrics["method"] == "joint", "centre_error"]
    assert joint.median() > 2 * sep.median()


def test_crb_and_rmse_rows(paper_run):
    _, _, folder = paper_run
    summary = pd.read_csv(folder / "summary.csv").set_index(["method", "metric"])
    metrics = pd.read_csv(folder / "metrics.csv")
    crb = crb_circle_nuisance_angles(1.5 * np.pi * np.array(structure_fit.PAPER_ANGLE_FRACTIONS), 0.1)
    assert summary.loc[("crb", "centre_rmse"), "mean"] == pytest.approx(np.sqrt(crb[0, 0] + crb[1, 1]), rel=1e-12)
    assert summary.loc[("crb", "radius_rmse"), "mean"] == pytest.approx(np.sqrt(crb[2, 2]), rel=1e-12)
    for method in ("joint", "separate"):
        errors = metrics.loc[metrics["method"] == method, "centre_error"].to_numpy()
        row = summary.loc[(method, "centre_rmse")]
        assert row["mean"] == pytest.approx(np.sqrt(np.mean(errors ** 2)), rel=1e-12)
        assert row["ci_low"] <= row["mean"] <= row["ci_high"] and row["n"] == N
    table = pd.read_csv(folder / "table1.csv").set_index("method")
    assert table.loc["joint", "paper_centre_error"] == 0.71
    assert table.loc["separate", "paper_radius_error"] == 0.039


def test_fair_protocol_separate_fit_near_the_bound(compose_exp):
    cfg = compose_exp("structure_fit", "protocol=fair", "arc_deg=180", "n_samples=20", "n_seeds=60",
                      "sweep.n_seeds=0")
    out = structure_fit.run(cfg)
    assert "crb_joint" in set(out.metrics["method"])
    rmse = out.summary_extra.set_index(["method", "metric"])["mean"]
    ratio = rmse[("separate", "centre_rmse")] / rmse[("crb", "centre_rmse")]
    # RMSE over 60 runs: relative SE ≈ ½·std(e²)/(mean(e²)·√60), from the run itself; the
    # 2000-run ratio is the reference; 4 SE covers Monte Carlo noise.
    e2 = out.metrics.loc[out.metrics["method"] == "separate", "centre_error"].to_numpy() ** 2
    rel_se = 0.5 * e2.std(ddof=1) / (e2.mean() * np.sqrt(N))
    assert abs(ratio - FAIR_RATIO_2000) < 4 * rel_se * FAIR_RATIO_2000
    # and the bound of the constant-rate model is the tighter one
    assert rmse[("crb_joint", "centre_rmse")] < rmse[("crb", "centre_rmse")]


def test_same_seed_gives_identical_metrics_bytes(paper_run, compose_exp):
    _, _, folder = paper_run
    again = execute(compose_exp("structure_fit", *CUT))
    assert (again / "metrics.csv").read_bytes() == (folder / "metrics.csv").read_bytes()
    assert (again / "summary.csv").read_bytes() == (folder / "summary.csv").read_bytes()


@pytest.mark.parametrize("override, match", [
    ("protocol=fair;arc_deg=360;n_samples=3", "n_samples: 3 samples over 360° give 2 distinct angles"),
    ("n_samples=2", "n_samples: expected an integer ≥ 3, got 2"),
    ("arc_deg=-5", r"arc_deg: expected a number > 0.0 and ≤ 360.0, got -5.0"),
    ("arc_deg=400", r"arc_deg: expected a number > 0.0 and ≤ 360.0, got 400.0"),
    ("protocol=best", "protocol: expected one of paper, fair; got 'best'"),
    ("noise_sigma=0", "noise_sigma: expected a number > 0.0"),
    ("sweep.arcs_deg=[90,0]", r"sweep.arcs_deg\[1\]: expected a number > 0 and ≤ 360, got 0.0"),
    ("sweep.n_samples=[10,2]", r"sweep.n_samples\[1\]: expected an integer ≥ 3, got 2"),
])
def test_bad_overrides_raise_and_leave_no_folder(compose_exp, tmp_path, override, match):
    cfg = compose_exp("structure_fit", *override.split(";"))
    with pytest.raises(ConfigError, match=match):
        execute(cfg)
    assert not (tmp_path / "results").exists()


def test_cli_bad_override_prints_one_line_and_exits_2(tmp_path):
    out = tmp_path / "cli"
    result = subprocess.run(
        [sys.executable, "experiments/run.py", "+exp=structure_fit", "n_samples=2", f"out_dir={out}"],
        cwd=REPO, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == ["error: n_samples: expected an integer ≥ 3, got 2"]
    assert not out.exists()
