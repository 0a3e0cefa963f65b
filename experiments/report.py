"""Build the reproduction report ``paper/report.pdf`` from results folders.

    python experiments/report.py                      # newest complete run of each experiment
    python experiments/report.py results/dynamic_slam/<run> …   # or the folders named
    python experiments/report.py --results /tmp/results --paper-dir /tmp/paper
    python experiments/report.py --no-pdf             # tables and figures only
    python experiments/report.py --quick …            # the title page says the runs are quick ones

Runs are grouped by experiment and *variant* (for SLAM the world, the field of
view, noise-free controls, a non-default noise; for the others a non-default
protocol, selector or input file: see :func:`variant_of`), key
``<experiment>[-<variant>]``. For each key the newest complete folder (or the
one named) gives:

- ``<paper-dir>/generated/<key>/<table>.tex``: its tables (:data:`TABLES`),
- ``<paper-dir>/generated/<key>/<figure>.pdf``: its figures,
- macros in ``generated/values.tex``: every summary value, the best method per
  metric, the folder and git sha it came from (``stslam.render.report_tables``),
  and the title-page note on whether every run's code is the code on disk now
  (``stslam.render.report_provenance``),

then ``latexmk -pdf report.tex`` runs in the paper folder. Numbers come only
from ``summary.csv`` and ``<paper-dir>/paper_numbers.csv`` (the back-end comparison: from both runs'
``metrics.csv``, :mod:`stslam.render.backend_tables`). Keys that
``report.tex`` does not mention get their main table in an appendix
(``generated/extra.tex``), so no run is silently left out.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import yaml

from stslam.config.readers import lookup
from stslam.errors import InputFileError, StslamError
from stslam.experiments.cli import main_guard
from stslam.render.report_tables import (TableSpec, available_macro, best_macros, comparison_table, confusion_table,
                                  folder_name_macro,
                                  paper_macros,
                                  paper_source_macro, paper_source_note, source_macro, source_text,
                                  value_macros)
from stslam.experiments.reproduce import code_origins
from stslam.io.git_tree import ChangeCache, head_commit
from stslam.io.results import complete_runs, git_state
from stslam.render.backend_tables import backend_table, cross_macros, ratio_macros
from stslam.render.report_provenance import provenance_macros

REPO = Path(__file__).resolve().parent.parent
PAPER = REPO / "paper"

_SLAM = ("odometry", "ekf_slam", "dyn_slam", "ekf_slam_gated", "a_slam", "a_slam_truth_onsets", "oracle")

# experiment -> its tables; the first is the main one (the only one an unmentioned variant shows)
TABLES = {
    "structure_fit": (
        TableSpec("main", ("joint", "separate", "crb"), ("centre_error", "radius_error")),
        TableSpec("rmse", ("joint", "separate", "crb"), ("centre_rmse", "radius_rmse"), paper=False)),
    "temporal_order": (
        TableSpec("main", None, ("filtered_rmse", "pred1_rmse", "predk_rmse", "loglik")),),
    "articulation_estimation": (
        TableSpec("main", ("static", "prismatic", "revolute"), ("correct", "selection_step", "wrong_argmax_step")),),
    "dynamic_slam": (
        TableSpec("main", _SLAM, ("ate_m", "rpe_m")),
        TableSpec("consistency", _SLAM, ("nees", "nees_in_band", "nees_frac_out", "diverged"), paper=False),
        TableSpec("smoothing", _SLAM, ("ate_m", "ate_online_m", "nees", "nees_online"), paper=False)),
    "fridge": (
        TableSpec("main", _SLAM, ("ate_m", "rpe_m")),
        TableSpec("axis", ("a_slam",), ("axis_angle_deg", "axis_dist_m", "axis_angle_deg_true_poses",
                                        "axis_dist_m_true_poses"), paper=False)),
    "classify_tracks": (
        TableSpec("main", None, ("correct", "decision_delay_s", "axis_angle_deg", "axis_dist_m",
                                 "radius_error_m")),),
}

# SPEC 5.2: σ = 0.04 m is the observation noise of every default config
DEFAULT_SIGMA_M = 0.04


def _sigma_part(value) -> list[str]:
    if isinstance(value, (int, float)) and not math.isclose(float(value), DEFAULT_SIGMA_M):
        return [f"sigma{float(value):g}"]
    return []


def variant_of(config: dict) -> str:
    """The variant of a run within its experiment ('' for the default settings).

    dynamic_slam: ``<world>[-pinhole][-noisefree_controls][-sigma<σ>][-order1][-iter<k>]``
    (the authors' setting of SPEC 8.4 is ``paper_square-pinhole-noisefree_controls``;
    ``order1``: first-order motion noise, ``iter<k>``: iterated updates);
    structure_fit: the protocol when not ``paper``; temporal_order: ``csv`` for a
    user's trace, the filter when not ``tuned``; articulation_estimation: the
    selector when not ``threshold``, a non-default noise; fridge: ``recording``
    for a user's MCAP.
    """
    exp = config.get("exp_name")
    parts: list[str] = []
    if exp == "dynamic_slam":
        parts.append(str(lookup(config, "world.name", "world")))
        if lookup(config, "sensor.fov", "cone") != "cone":
            parts.append(str(lookup(config, "sensor.fov", None)))
        if lookup(config, "robot.control_noise", True) is False:
            parts.append("noisefree_controls")
        parts += _sigma_part(lookup(config, "sensor.sigma", None))
        if lookup(config, "motion_noise_order", 2) != 2:
            parts.append(f"order{lookup(config, 'motion_noise_order', None)}")
        if lookup(config, "update_iterations", 1) != 1:
            parts.append(f"iter{lookup(config, 'update_iterations', None)}")
    elif exp == "structure_fit" and lookup(config, "protocol", "paper") != "paper":
        parts.append(str(lookup(config, "protocol", None)))
    elif exp == "temporal_order":
        if lookup(config, "trace.csv", None) is not None:
            parts.append("csv")
        if lookup(config, "filter.name", "tuned") != "tuned":
            parts.append(str(lookup(config, "filter.name", None)))
    elif exp == "articulation_estimation":
        if lookup(config, "selection.selector", "threshold") != "threshold":
            parts.append(str(lookup(config, "selection.selector", None)))
        parts += _sigma_part(lookup(config, "articulation.noise_sigma_m", None))
    elif exp == "fridge" and lookup(config, "mcap", None) is not None:
        parts.append("recording")
    if exp in ("dynamic_slam", "fridge") and lookup(config, "backend", "ekf") != "ekf":
        parts.append(str(lookup(config, "backend", None)))
    return "-".join(re.sub(r"[^A-Za-z0-9_.]", "_", p) for p in parts)


def _read_run(folder: Path) -> tuple[str, str, dict, pd.DataFrame, dict]:
    try:
        config = yaml.safe_load((folder / "config.yaml").read_text())
        summary = pd.read_csv(folder / "summary.csv")
        version = json.loads((folder / "version.json").read_text())
    except (OSError, yaml.YAMLError, ValueError, pd.errors.ParserError) as error:
        raise InputFileError(folder, f"not a complete results folder ({error})") from None
    if not isinstance(config, dict) or config.get("exp_name") not in TABLES:
        raise InputFileError(folder / "config.yaml", f"exp_name: expected one of {', '.join(TABLES)}")
    return config["exp_name"], variant_of(config), config, summary, version


def choose_runs(results: Path, named: list[Path]) -> dict[str, Path]:
    """key ``<experiment>[-<variant>]`` → results folder: the folders named, else the newest of each."""
    chosen: dict[str, Path] = {}
    candidates = named or [run for exp in TABLES for run in complete_runs(results, exp)]
    for folder in candidates:  # complete_runs is oldest first (folder names start with the time), so newer win
        exp, variant, *_ = _read_run(folder)
        chosen[exp if not variant else f"{exp}-{variant}"] = folder
    return chosen


def _paper_rows(paper_numbers: pd.DataFrame, exp: str, variant: str) -> pd.DataFrame | None:
    """The article's values for a run: for its default settings, and for every SLAM world but the
    kitchen (which the article has no counterpart of); none for other protocols or inputs."""
    if variant and not (exp == "dynamic_slam" and "kitchen" not in variant.split("-")):
        return None
    rows = paper_numbers[paper_numbers["experiment"] == exp]
    return rows if len(rows) else None


def _read_paper_numbers(path: Path) -> pd.DataFrame:
    """``paper_numbers.csv``, values kept as text (printed as the article prints them)."""
    try:
        table = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, ValueError, pd.errors.ParserError) as error:
        raise InputFileError(path, f"cannot read the article's numbers ({error})") from None
    missing = {"experiment", "method", "metric", "value", "source"} - set(table.columns)
    if missing:
        raise InputFileError(path, f"missing columns {', '.join(sorted(missing))}", line=1)
    for i, value in enumerate(table["value"]):
        try:
            float(value)
        except ValueError:
            raise InputFileError(path, f"value: expected a number, got {value!r}", line=i + 2) from None
    return table


def code_macros(runs: dict[str, tuple[str, dict]], quick: bool) -> str:
    """The title-page macros for report key → (experiment, ``version.json``), against this checkout."""
    head = head_commit(REPO)
    sha, dirty = git_state(REPO)
    origins = code_origins(REPO, runs, head, ChangeCache(REPO).changed)
    return provenance_macros(origins, sha, dirty, quick)


def _read_metrics(folder: Path) -> pd.DataFrame:
    try:
        return pd.read_csv(folder / "metrics.csv")
    except (OSError, ValueError, pd.errors.ParserError) as error:
        raise InputFileError(folder, f"not a complete results folder ({error})") from None


def backend_outputs(chosen: dict[str, Path], out: Path) -> list[str]:
    """``<key>/backends.tex`` for every iSAM2 run beside its EKF twin (the key without ``-isam2``; EKF
    columns empty when that run is missing), and the ratio and cross-method macros
    (:mod:`stslam.render.backend_tables`); an EKF run gets the cross-method macros of its own methods."""
    macros = []
    for key, folder in sorted(chosen.items()):
        twin = key.removesuffix("-isam2")
        if twin != key:
            ekf = _read_metrics(chosen[twin]) if twin in chosen else None
            isam2 = _read_metrics(folder)
            (out / key / "backends.tex").write_text(backend_table(ekf, isam2, list(_SLAM)))
            macros.append(ratio_macros(key, ekf, isam2, list(_SLAM)))
            macros.append(cross_macros(key, ekf, isam2, list(_SLAM)))
        else:  # an EKF SLAM run: its methods against each other (e.g. \crossratio{fridge}{a_slam}{ekf_slam_gated})
            metrics = _read_metrics(folder)
            if {"seed", "method", "ate_m"} <= set(metrics.columns):
                macros.append(cross_macros(key, metrics, metrics, list(_SLAM)))
    return macros


def write_generated(chosen: dict[str, Path], paper_dir: Path, quick: bool = False) -> list[str]:
    """Tables, figures and macros under ``paper_dir/generated``; returns the keys written.

    ``quick``: the runs are ``experiments/reproduce.py --quick`` ones, and the title page says so.
    """
    out = paper_dir / "generated"
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    paper_numbers = _read_paper_numbers(paper_dir / "paper_numbers.csv")
    report_text = (paper_dir / "report.tex").read_text() if (paper_dir / "report.tex").is_file() else ""
    macros = [paper_macros(paper_numbers)]
    extra = []
    versions = {}
    for key, folder in sorted(chosen.items()):
        exp, variant, _, summary, version = _read_run(folder)
        versions[key] = (exp, version)
        paper = _paper_rows(paper_numbers, exp, variant)
        (out / key).mkdir()
        for spec in TABLES[exp]:
            methods = list(spec.methods or pd.unique(summary["method"]))
            shown = paper if spec.paper else None
            (out / key / f"{spec.name}.tex").write_text(
                comparison_table(summary, methods, list(spec.metrics), shown))
            note = paper_source_note(shown, list(spec.metrics))
            if note:
                macros.append(paper_source_macro(key, spec.name, note))
            macros.append(best_macros(key, summary, methods, list(spec.metrics)))
        folder = folder.resolve()
        n_seeds = int(summary["n"].max()) if len(summary) else 0
        macros.append(source_macro(key, source_text([folder.parent.parent.name, folder.parent.name, folder.name],
                                                     str(version.get("git_sha", "?")),
                                                     bool(version.get("git_dirty")), n_seeds)))
        macros.append(folder_name_macro(key, folder.parent.name, folder.name))
        macros.append(value_macros(key, summary))
        macros.append(available_macro(key))
        if (folder / "decisions.csv").is_file():  # A-SLAM's final model per true model (SPEC 18)
            (out / key / "confusion.tex").write_text(confusion_table(pd.read_csv(folder / "decisions.csv")))
        figures = folder / "figures"
        if figures.is_dir():
            for pdf in sorted(figures.glob("*.pdf")):
                shutil.copy2(pdf, out / key / pdf.name)
        if "{" + key + "}" not in report_text:
            extra.append(f"\\resulttable{{{key}}}{{main}}{{Results of \\texttt{{{key.replace('_', chr(92) + '_')}}}"
                         f" (a run this report's text does not discuss).}}\n")
    macros.extend(backend_outputs(chosen, out))
    macros.append(code_macros(versions, quick))
    (out / "values.tex").write_text("".join(macros))
    if extra:
        (out / "extra.tex").write_text("\\clearpage\n\\section{Other runs found}\n" + "".join(extra))
    return sorted(chosen)


def overfull_boxes(log_text: str) -> list[str]:
    """The "Overfull \\hbox" lines of a LaTeX log."""
    return [line for line in log_text.splitlines() if line.startswith("Overfull \\hbox")]


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


@main_guard("the report was not built; <paper-dir>/generated/ may be incomplete")
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="Build paper/report.pdf from results folders.")
    parser.add_argument("runs", nargs="*", type=Path, help="results folders to use (default: newest of each)")
    parser.add_argument("--results", type=Path, default=Path("results"), help="root of results (default results)")
    parser.add_argument("--paper-dir", type=Path, default=PAPER,
                        help="folder holding report.tex and paper_numbers.csv (default paper/)")
    parser.add_argument("--no-pdf", action="store_true", help="write <paper-dir>/generated/ only")
    parser.add_argument("--quick", action="store_true",
                        help="say on the title page that the runs used reproduce.py --quick's seed counts")
    args = parser.parse_args(argv)
    chosen = choose_runs(args.results, args.runs)
    if not chosen:
        raise StslamError(f"no complete results folder under {args.results}; run an experiment first")
    for key, folder in sorted(chosen.items()):
        print(f"{key}: {folder}")
    write_generated(chosen, args.paper_dir, quick=args.quick)
    if not args.no_pdf:
        pdf = build_pdf(args.paper_dir)
        overfull = overfull_boxes((args.paper_dir / "report.log").read_text(errors="replace"))
        for line in overfull:
            print(f"warning: {line} (report.log)")
        print(f"report: {pdf}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
