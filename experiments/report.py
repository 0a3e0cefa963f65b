"""Build the reproduction report ``paper/report.pdf`` from results folders.

    python experiments/report.py                      # newest complete run of each experiment
    python experiments/report.py results/dynamic_slam/<run> …   # or the folders named
    python experiments/report.py --no-pdf             # tables and figures only

For each experiment (and, for SLAM, each world) it picks the newest complete
results folder, writes its table as ``paper/generated/<key>_table.tex``, the
folder and git sha it came from as a macro ``\\src@<key>``, copies its figures to
``paper/generated/<key>/`` and defines every summary value as a macro
(``\\val{<key>}{<method>}{<metric>}{<stat>}``) in ``values.tex``; then runs
``latexmk -pdf report.tex`` in ``paper/``. Numbers come only from
``summary.csv`` and ``paper/paper_numbers.csv``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import yaml

from stslam.errors import InputFileError, StslamError
from stslam.report_tables import comparison_table, latex_escape, value_macros
from stslam.results import complete_runs

REPO = Path(__file__).resolve().parent.parent
PAPER = REPO / "paper"

# experiment -> (row methods in order, metric columns in order); None = all found
TABLES = {
    "structure_fit": (["joint", "separate", "crb"],
                      ["centre_error", "radius_error", "centre_rmse", "radius_rmse"]),
    "temporal_order": (None, ["filtered_rmse", "pred1_rmse", "predk_rmse", "loglik"]),
    "articulation_estimation": (None, ["selection_step", "correct", "wrong_argmax_step"]),
    "dynamic_slam": (["ekf_slam", "dyn_slam", "ekf_slam_gated", "a_slam", "oracle"],
                     ["ate_m", "rpe_m", "nees"]),
    "fridge": (["ekf_slam", "dyn_slam", "ekf_slam_gated", "a_slam", "oracle"],
               ["ate_m", "rpe_m", "axis_angle_deg", "axis_dist_m"]),
    "classify_tracks": (None, ["correct", "selection_time_s", "fit_residual_m"]),
}


def variant_of(config: dict) -> str:
    """Sub-key of a run within its experiment: the world for SLAM runs ('' otherwise).

    Runs in the authors' setting (noise-free controls) get the suffix ``authors``.
    """
    world = config.get("world")
    if not isinstance(world, dict) or "name" not in world:
        return ""
    name = str(world["name"])
    robot = config.get("robot") or {}
    if robot.get("control_noise") is False:
        name += "-authors"
    return name


def _read_run(folder: Path) -> tuple[str, str, dict, pd.DataFrame, dict]:
    try:
        config = yaml.safe_load((folder / "config.yaml").read_text())
        summary = pd.read_csv(folder / "summary.csv")
        version = json.loads((folder / "version.json").read_text())
    except (OSError, yaml.YAMLError, ValueError, pd.errors.ParserError) as error:
        raise InputFileError(folder, f"not a complete results folder ({error})") from None
    return config["exp_name"], variant_of(config), config, summary, version


def choose_runs(results: Path, named: list[Path]) -> dict[tuple[str, str], Path]:
    """(experiment, variant) → results folder: the folders named, else the newest of each."""
    chosen: dict[tuple[str, str], Path] = {}
    candidates = named or [run for exp in TABLES for run in complete_runs(results, exp)]
    for folder in candidates:  # complete_runs is oldest first, so newer runs win
        exp, variant, *_ = _read_run(folder)
        chosen[(exp, variant)] = folder
    return chosen


def write_generated(chosen: dict[tuple[str, str], Path], out: Path) -> list[str]:
    """Tables, sources, figures and value macros under ``out``; returns the keys written."""
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    paper_numbers = pd.read_csv(PAPER / "paper_numbers.csv")
    macros, sources, keys = [], [], []
    for (exp, variant), folder in sorted(chosen.items()):
        _, _, config, summary, version = _read_run(folder)
        key = exp if not variant else f"{exp}-{variant}"
        methods, metrics = TABLES.get(exp, (None, None))
        methods = methods or list(pd.unique(summary["method"]))
        metrics = metrics or list(pd.unique(summary["metric"]))
        paper = paper_numbers[paper_numbers["experiment"] == exp] if not variant.endswith("kitchen") else None
        (out / f"{key}_table.tex").write_text(comparison_table(summary, methods, metrics, paper))
        try:
            shown = folder.resolve().relative_to(REPO)
        except ValueError:
            shown = folder.resolve()
        sources.append(
            f"\\expandafter\\def\\csname src@{key}\\endcsname{{Results folder "
            f"\\texttt{{{latex_escape(str(shown))}}}, git \\texttt{{{latex_escape(version.get('git_sha', '?'))}}}"
            f"{' (dirty)' if version.get('git_dirty') else ''}, "
            f"{int(summary['n'].max()) if len(summary) else 0} seeds.}}\n")
        figures = folder / "figures"
        if figures.is_dir():
            shutil.copytree(figures, out / key, ignore=shutil.ignore_patterns("*.png"))
        macros.append(value_macros(key, summary))
        keys.append(key)
    (out / "values.tex").write_text("".join(macros) + "".join(sources))
    (out / "available.tex").write_text(
        "".join(f"\\expandafter\\def\\csname have@{k}\\endcsname{{1}}\n" for k in keys))
    return keys


def build_pdf(paper_dir: Path) -> Path:
    """Run latexmk (pdflatex) in ``paper_dir``; returns the PDF path."""
    if shutil.which("latexmk") is None:
        raise StslamError("latexmk not found: install texlive-latex-extra texlive-publishers "
                          "texlive-science latexmk (Debian) to build the PDF")
    done = subprocess.run(["latexmk", "-pdf", "-interaction=nonstopmode", "-halt-on-error", "report.tex"],
                          cwd=paper_dir, capture_output=True, text=True)
    if done.returncode != 0:
        tail = "\n".join(done.stdout.splitlines()[-25:])
        raise StslamError(f"latexmk failed in {paper_dir} (see report.log):\n{tail}")
    return paper_dir / "report.pdf"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Build paper/report.pdf from results folders.")
    parser.add_argument("runs", nargs="*", type=Path, help="results folders to use (default: newest of each)")
    parser.add_argument("--results", type=Path, default=Path("results"), help="root of results (default results)")
    parser.add_argument("--paper-dir", type=Path, default=PAPER, help="folder holding report.tex")
    parser.add_argument("--no-pdf", action="store_true", help="write paper/generated/ only")
    args = parser.parse_args(argv)
    try:
        chosen = choose_runs(args.results, args.runs)
        if not chosen:
            raise StslamError(f"no complete results folder under {args.results}; run an experiment first")
        keys = write_generated(chosen, args.paper_dir / "generated")
        print("tables: " + ", ".join(keys))
        if not args.no_pdf:
            print(f"report: {build_pdf(args.paper_dir)}")
    except StslamError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
