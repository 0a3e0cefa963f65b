"""The reproduction report (issue 10): built from small runs of every experiment, then read back.

A module fixture runs each experiment cut down (few seeds; the fridge on a
90-frame 160 × 120 sequence, as in test_fridge.py) into a temporary results
root, copies ``paper/report.tex`` and ``paper/paper_numbers.csv`` to a temporary
paper folder (the repository's ``paper/`` is never written), runs
``experiments/report.py`` on them and reads the PDF back with ``pdftotext``.
"""

from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from stslam.render.report_tables import (comparison_table, format_number, method_label, paper_number,
                                  source_text)
from stslam.experiments.runner import execute
from stslam.render.backend_tables import ate_ratio, backend_table, cross_macros
from stslam.io.track_files import format_track, write_track_file
from stslam.sim.track_generator import generate_tracks

from conftest import REPO, compose_config

REPORT_PY = REPO / "experiments" / "report.py"


def _load_report_module():
    spec = importlib.util.spec_from_file_location("stslam_report_script", REPORT_PY)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


report = _load_report_module()


def _small_runs(results: Path, scratch: Path) -> dict[str, Path]:
    """One cut-down run of every experiment; key → results folder."""
    tracks = scratch / "tracks"
    for i, track in enumerate(generate_tracks(4, 500)):
        write_track_file(tracks / f"track_{i:02d}_{track.kind}.txt",
                         format_track(track.points_world, None, track.metadata()))
    runs = {
        "structure_fit": ["n_seeds=20", "sweep.n_seeds=3", "sweep.arcs_deg=[90,180]", "sweep.n_samples=[7,20]"],
        "temporal_order": ["n_seeds=3"],
        "articulation_estimation": ["n_seeds=2"],
        "dynamic_slam": ["n_seeds=3"],
        "classify_tracks": [f"tracks.glob={tracks}/*.txt", "max_figures=1"],
        "fridge": ["n_seeds=1", f"data_dir={scratch / 'data'}", "sequence.n_frames=90", "sequence.width=160",
                   "sequence.height=120", "landmarks.min_track_frames=20"],
    }
    folders = {}
    for exp, overrides in runs.items():
        folder = execute(compose_config(exp, overrides, out_dir=results))
        key = "dynamic_slam-square_centred" if exp == "dynamic_slam" else exp
        folders[key] = folder
    return folders


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """(folders by key, temporary paper folder, pdftotext -layout text, report.py stdout)."""
    for tool in ("latexmk", "pdftotext"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} is not on PATH (.ci/run installs it with texlive and poppler-utils)")
    scratch = tmp_path_factory.mktemp("report")
    folders = _small_runs(scratch / "results", scratch)
    paper = scratch / "paper"
    paper.mkdir()
    for name in ("report.tex", "paper_numbers.csv"):
        shutil.copy2(REPO / "paper" / name, paper / name)
    done = subprocess.run([sys.executable, str(REPORT_PY), "--results", str(scratch / "results"),
                           "--paper-dir", str(paper)], capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 0, done.stdout + done.stderr
    text = subprocess.run(["pdftotext", "-layout", str(paper / "report.pdf"), "-"],
                          capture_output=True, text=True, check=True).stdout
    return folders, paper, text, done.stdout


def _flat(text: str) -> str:
    return " ".join(text.split())


def test_pdf_exists_and_every_run_is_named(built):
    folders, paper, text, _ = built
    assert (paper / "report.pdf").stat().st_size > 10_000
    flat = _flat(text)
    for key, folder in folders.items():
        # every table and figure caption ends with "Source: <root>/<exp>/<folder> (git <sha>…)"
        assert folder.name in flat, key
        assert f"Not available: no complete results folder for {key}." not in flat
    assert "is missing from the results folder" not in flat


def test_table_ii_rows_show_the_summary_means(built):
    folders, _, text, _ = built
    summary = pd.read_csv(folders["dynamic_slam-square_centred"] / "summary.csv").set_index(["method", "metric"])
    lines = [line.strip() for line in text.splitlines()]
    methods = ["ekf_slam", "dyn_slam", "ekf_slam_gated", "a_slam", "oracle"]
    for method in methods:
        ate = format_number(summary.loc[(method, "ate_m"), "mean"])
        rpe = format_number(summary.loc[(method, "rpe_m"), "mean"])
        label = method_label(method).replace("\\ ", " ")
        # a table row starts with the method's label and holds its ATE and RPE means as the table formats them
        rows = [line for line in lines if line.startswith(label + " ") and ate in line and rpe in line]
        assert rows, (method, ate, rpe)


def test_main_tables_hold_every_summary_mean(built):
    folders, _, text, _ = built
    flat = _flat(text)
    for key, folder in folders.items():
        exp = key.split("-")[0]
        summary = pd.read_csv(folder / "summary.csv")
        spec = report.TABLES[exp][0]
        shown = summary[summary["metric"].isin(spec.metrics)]
        if spec.methods is not None:
            shown = shown[shown["method"].isin(spec.methods)]
        assert len(shown) > 0, key
        for _, row in shown.iterrows():
            assert format_number(row["mean"]) in flat, (key, row["method"], row["metric"])


def test_paper_numbers_are_printed_beside_ours(built):
    _, _, text, _ = built
    paper_numbers = pd.read_csv(REPO / "paper" / "paper_numbers.csv", dtype=str)
    a_slam = paper_numbers[(paper_numbers["experiment"] == "dynamic_slam") & (paper_numbers["method"] == "a_slam")]
    rows = [line.strip() for line in text.splitlines() if line.strip().startswith("A-SLAM ")]
    for value in a_slam["value"]:
        assert any(value in row for row in rows), value


def test_latex_log_has_no_overfull_boxes(built):
    _, paper, _, stdout = built
    log = (paper / "report.log").read_text(errors="replace")
    assert report.overfull_boxes(log) == []
    assert "warning:" not in stdout


def test_repository_paper_folder_is_not_written(built):
    _, paper, _, _ = built
    assert paper != REPO / "paper" and (paper / "generated" / "values.tex").is_file()


# ---- pure parts (no LaTeX needed) -------------------------------------------------------------

@pytest.mark.parametrize("value, text", [
    (0.019481669, "0.0195"), (14.98421, "15.0"), (0.0, "0"), (-7.9412, "-7.94"), (123.4, "123"),
    (float("nan"), "--"), (3.2e-6, "3.20e-06"),
])
def test_format_number_three_significant_figures(value, text):
    assert format_number(value) == text


def test_paper_numbers_are_printed_as_written():
    assert paper_number("0.60") == "0.60" and paper_number(" 0.014") == "0.014"


def test_comparison_table_puts_paper_beside_ours_and_skips_absent_rows():
    summary = pd.DataFrame({"method": ["a_slam", "a_slam"], "metric": ["ate_m", "rpe_m"], "mean": [0.02, 0.03],
                            "median": [0.02, 0.03], "ci_low": [0.01, float("nan")], "ci_high": [0.03, float("nan")],
                            "n": [3, 3]})
    paper = pd.DataFrame({"method": ["a_slam"], "metric": ["ate_m"], "value": ["0.014"], "source": ["Table II"]})
    table = comparison_table(summary, ["ekf_slam", "a_slam"], ["ate_m", "rpe_m"], paper)
    body = [line for line in table.splitlines() if line.startswith("A-SLAM")]
    assert body == ["A-SLAM & 0.0200 {\\scriptsize[0.0100, 0.0300]} & 0.014 & 0.0300 \\\\"]
    assert "EKF SLAM" not in table  # absent from the summary: no row
    assert "\\multicolumn{2}{c}{ATE (m)}" in table and "\\multicolumn{1}{c}{RPE (m)}" in table


def test_source_text_keeps_the_folder_name_whole():
    text = source_text(["results", "dynamic_slam", "20261123-225033-65b541b"], "65b541b", True, 3)
    assert "\\mbox{\\texttt{20261123-225033-65b541b}}" in text
    assert "dynamic\\_slam/" in text and "uncommitted changes; 3 seeds" in text


@pytest.mark.parametrize("config, variant", [
    ({"exp_name": "dynamic_slam", "world": {"name": "square_centred"}, "sensor": {"fov": "cone", "sigma": 0.04},
      "robot": {"control_noise": True}}, "square_centred"),
    ({"exp_name": "dynamic_slam", "world": {"name": "paper_square"}, "sensor": {"fov": "pinhole", "sigma": 0.04},
      "robot": {"control_noise": False}}, "paper_square-pinhole-noisefree_controls"),
    ({"exp_name": "dynamic_slam", "world": {"name": "square_centred"}, "sensor": {"fov": "cone", "sigma": 0.2},
      "robot": {"control_noise": True}}, "square_centred-sigma0.2"),
    ({"exp_name": "dynamic_slam", "world": {"name": "kitchen"}, "sensor": {"fov": "cone", "sigma": 0.04},
      "robot": {"control_noise": True}, "motion_noise_order": 1, "update_iterations": 3}, "kitchen-order1-iter3"),
    ({"exp_name": "dynamic_slam", "world": {"name": "kitchen"}, "sensor": {"fov": "cone", "sigma": 0.04},
      "robot": {"control_noise": True}, "motion_noise_order": 2, "update_iterations": 1}, "kitchen"),
    ({"exp_name": "structure_fit", "protocol": "paper"}, ""),
    ({"exp_name": "structure_fit", "protocol": "fair"}, "fair"),
    ({"exp_name": "temporal_order", "trace": {"csv": None}, "filter": {"name": "paper"}}, "paper"),
    ({"exp_name": "articulation_estimation", "selection": {"selector": "imm"},
      "articulation": {"noise_sigma_m": 0.04}}, "imm"),
    ({"exp_name": "fridge", "mcap": "rec.mcap"}, "recording"),
    ({"exp_name": "dynamic_slam", "world": {"name": "kitchen"}, "backend": "isam2"}, "kitchen-isam2"),
    ({"exp_name": "fridge", "backend": "isam2"}, "isam2"),
    ({"exp_name": "fridge", "backend": "ekf"}, ""),
])
def test_variant_of_names_non_default_settings(config, variant):
    assert report.variant_of(config) == variant


def test_paper_rows_only_for_comparable_settings():
    numbers = pd.DataFrame({"experiment": ["dynamic_slam", "structure_fit"], "method": ["a_slam", "joint"],
                            "metric": ["ate_m", "centre_error"], "value": ["0.014", "0.71"], "source": ["T2", "T1"]})
    assert report._paper_rows(numbers, "dynamic_slam", "paper_square-pinhole-noisefree_controls") is not None
    assert report._paper_rows(numbers, "dynamic_slam", "kitchen") is None
    assert report._paper_rows(numbers, "structure_fit", "fair") is None
    assert report._paper_rows(numbers, "structure_fit", "") is not None


def test_empty_results_root_is_an_error(tmp_path):
    done = subprocess.run([sys.executable, str(REPORT_PY), "--results", str(tmp_path), "--paper-dir",
                           str(tmp_path / "paper"), "--no-pdf"], capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 2
    assert done.stderr.startswith("error: no complete results folder under") and "Traceback" not in done.stderr


def test_bad_paper_numbers_file_names_its_line(tmp_path):
    (tmp_path / "paper_numbers.csv").write_text("experiment,method,metric,value,source\n"
                                                "dynamic_slam,a_slam,ate_m,0.014,Table II\n"
                                                "dynamic_slam,a_slam,rpe_m,zero,Table II\n")
    from stslam.errors import InputFileError
    with pytest.raises(InputFileError, match=r"paper_numbers.csv:3: value: expected a number, got 'zero'"):
        report._read_paper_numbers(tmp_path / "paper_numbers.csv")


def test_backend_table_compares_the_seeds_both_runs_have():
    ekf = pd.DataFrame({"seed": [0, 1, 2, 0, 1, 2], "method": ["a_slam"] * 3 + ["oracle"] * 3,
                        "ate_m": [0.02, 0.04, 9.0, 0.01, 0.01, 9.0], "nees": [3.0] * 6})
    isam2 = pd.DataFrame({"seed": [0, 1, 0, 1], "method": ["a_slam", "a_slam", "oracle", "oracle"],
                          "ate_m": [0.015, 0.03, 0.005, 0.005], "ate_online_m": [0.02] * 4,
                          "nees": [4.0] * 4, "nees_online": [3.5] * 4})
    assert ate_ratio(ekf, isam2, "a_slam") == pytest.approx(0.75)  # seed 2 is the EKF run's only
    table = backend_table(ekf, isam2, ["ekf_slam", "a_slam", "oracle"])
    assert table.count("\\\\") == 5  # header rows, two methods (ekf_slam is in neither run), the seed note
    assert "0.750" in table and "0.500" in table and "2 seeds common to both runs" in table
    alone = backend_table(None, isam2, ["a_slam", "oracle"])
    assert "2 seeds; no EKF run found" in alone and alone.count("--") == 6  # EKF ATE, ratio and EKF NEES, two methods
    # Each mean carries its 95% interval over the common seeds: A-SLAM's smoothed ATE 0.015, 0.03 has mean
    # 0.0225 ± t(0.975, 1) · 0.0106 / √2 = 0.0225 ± 0.0953; equal values (the oracle's) have no spread.
    a_slam_row = next(line for line in table.splitlines() if line.startswith("A-SLAM"))
    assert "0.0225 {\\scriptsize[-0.0728, 0.118]}" in a_slam_row
    oracle_row = next(line for line in table.splitlines() if line.startswith("Oracle"))
    assert "0.00500 {\\scriptsize[0.00500, 0.00500]}" in oracle_row


def test_cross_macros_compare_one_smoothed_method_with_another_under_the_ekf():
    ekf = pd.DataFrame({"seed": [0, 1, 2, 3] * 2, "method": ["ekf_slam_gated"] * 4 + ["a_slam"] * 4,
                        "ate_m": [0.010, 0.020, 0.010, 9.0, 0.5, 0.5, 0.5, 0.5]})
    isam2 = pd.DataFrame({"seed": [0, 1, 2], "method": ["a_slam"] * 3, "ate_m": [0.005, 0.010, 0.012]})
    text = cross_macros("fridge-isam2", ekf, isam2, ["ekf_slam_gated", "a_slam"])
    # seeds 0-2 (seed 3 is the EKF run's only): 0.009 / 0.01333 = 0.675; below on seeds 0 and 1, not on 2
    assert "\\csname cross@fridge-isam2@a_slam@ekf_slam_gated\\endcsname{0.675}" in text
    assert "\\csname below@fridge-isam2@a_slam@ekf_slam_gated\\endcsname{2 of 3}" in text
    assert "cross@fridge-isam2@ekf_slam_gated@a_slam" not in text  # the gated method has no iSAM2 rows here
    assert cross_macros("fridge-isam2", None, isam2, ["ekf_slam_gated", "a_slam"]) == ""
