"""Merge the jobs of a multirun sweep into one results folder.

    python experiments/run.py -m +exp=dynamic_slam seed=0,1,2,3 hydra/launcher=joblib
    python experiments/aggregate.py results/multirun/<stamp>

Each job leaves ``job.yaml`` (its overrides and results folder) in its sweep
sub-folder; this command concatenates their ``metrics.csv`` (adding a column per
swept parameter), summarises per swept value, draws metric-vs-parameter figures
and writes ``<out_dir>/<exp>_sweep/<stamp>-<sha>/`` like any other run.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import pandas as pd
import yaml

from stslam.errors import InputFileError
from stslam.eval.sweep import merge_jobs, parse_overrides, summarise_sweep
from stslam.experiments.cli import main_guard
from stslam.experiments.runner import TRACKED_PACKAGES
from stslam.io.results import write_run
from stslam.output import ExperimentOutput
from stslam.render.sweep import metric_vs_parameter


def _load_jobs(sweep_dir: Path):
    job_files = sorted(sweep_dir.glob("*/job.yaml"), key=lambda p: (len(p.parent.name), p.parent.name))
    if not job_files:
        raise InputFileError(sweep_dir, "no */job.yaml found: is this a sweep folder of experiments/run.py -m?")
    overrides, metrics, exps, folders = [], [], set(), []
    for job_file in job_files:
        try:
            job = yaml.safe_load(job_file.read_text())
            folder = Path(job["results_folder"])
            task = [str(o) for o in job["overrides"]]
        except (yaml.YAMLError, KeyError, TypeError) as error:
            raise InputFileError(job_file, f"expected keys results_folder and overrides ({error})") from None
        if not (folder / "metrics.csv").is_file():
            raise InputFileError(job_file, f"results folder {folder} has no metrics.csv (incomplete or removed)")
        config = yaml.safe_load((folder / "config.yaml").read_text())
        exps.add(config.get("exp_name"))
        overrides.append(parse_overrides(task))
        metrics.append(pd.read_csv(folder / "metrics.csv"))
        folders.append(str(folder))
    if len(exps) != 1:
        raise InputFileError(sweep_dir, f"jobs of more than one experiment: {sorted(map(str, exps))}")
    return exps.pop(), overrides, metrics, folders


def aggregate(sweep_dir: Path, out_dir: Path, metrics_to_plot: list[str] | None = None) -> Path:
    exp, overrides, metrics, folders = _load_jobs(sweep_dir)
    merged, keys = merge_jobs(overrides, metrics)
    summary = summarise_sweep(merged, keys)
    figures = {}
    wanted = metrics_to_plot or list(pd.unique(summary["metric"]))
    for key in keys:
        for metric in wanted:
            if (summary["metric"] == metric).any():
                figures[f"{metric}_vs_{key.replace('.', '_')}"] = metric_vs_parameter(summary, key, metric)
    output = ExperimentOutput(metrics=merged, figures=figures, tables={"sweep_summary": summary})
    config = {"exp_name": f"{exp}_sweep", "sweep_dir": str(sweep_dir), "swept": keys, "jobs": folders}
    # summary.csv pools every job per method (right for seed sweeps); sweep_summary.csv
    # keeps one block per swept value.
    return write_run(out_dir, f"{exp}_sweep", config, output, argv=sys.argv, packages=TRACKED_PACKAGES)


@main_guard("no results folder was written")
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("sweep_dir", type=Path, help="the multirun folder (results/multirun/<stamp>)")
    parser.add_argument("--out-dir", type=Path, default=Path("results"), help="root of results (default results)")
    parser.add_argument("--metrics", nargs="*", default=None, help="metrics to plot (default: all)")
    args = parser.parse_args(argv)
    folder = aggregate(args.sweep_dir, args.out_dir, args.metrics)
    print(f"results: {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
