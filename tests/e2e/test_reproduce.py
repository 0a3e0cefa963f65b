"""``python experiments/reproduce.py`` as a user runs it: --dry-run listings, bad arguments, and
(slow) a whole ``--quick`` build into temporary folders; the repository's results/ and paper/ are
never written."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from stslam.experiments.reproduce import PLAN, dependencies_for, planned
from stslam.io.git_tree import ChangeCache
from stslam.io.results import git_state

from conftest import REPO, compose_config

SCRIPT = REPO / "experiments" / "reproduce.py"


def _reproduce(*args: str, timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(SCRIPT), *args], cwd=REPO, capture_output=True, text=True,
                          timeout=timeout, env={"PYTHONPATH": str(REPO), "MPLBACKEND": "Agg",
                                                "PATH": "/usr/local/bin:/usr/bin:/bin"})


def _fake_run(results: Path, name: str, config: dict, **version) -> Path:
    """A complete-looking results folder (what reproduce reads of one: config, version, summary)."""
    folder = results / config["exp_name"] / name
    folder.mkdir(parents=True)
    (folder / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    (folder / "version.json").write_text(json.dumps({"git_sha": "abc1234", "git_dirty": False, **version}))
    (folder / "summary.csv").write_text("method,metric,mean,median,ci_low,ci_high,n\n")
    return folder


def _lines(done: subprocess.CompletedProcess, start: str) -> dict[str, str]:
    """key → line for the dry-run lines starting with ``start`` (``run``/``keep``)."""
    out = {}
    for line in done.stdout.splitlines():
        match = re.match(rf"{start} +(\S+) \(n_seeds=\d+\): (.*)", line)
        if match:
            out[match.group(1)] = match.group(2)
    return out


def test_dry_run_of_an_empty_results_root_lists_every_run_as_missing(tmp_path):
    done = _reproduce("--dry-run", "--quick", "--results", str(tmp_path / "r"), "--data-dir", str(tmp_path / "d"))
    assert done.returncode == 0, done.stderr
    runs = _lines(done, "run")
    assert list(runs) == [e.key for e in PLAN]
    assert all(reason == "missing: no complete run; estimated unknown" for reason in runs.values())
    out = done.stdout
    assert out.startswith(f"plan: {len(PLAN)} runs for the report at quick seed counts (--quick); results under ")
    assert f"first: python experiments/make_tracks.py out={tmp_path}/d/tracks n=100 seed=0" in out
    assert f"python experiments/run.py +exp=dynamic_slam world=kitchen update_iterations=3 n_seeds=2 " \
           f"out_dir={tmp_path / 'r'} progress=false" in out
    assert out.rstrip().splitlines()[-1].startswith(f"to run: {len(PLAN)} of {len(PLAN)} (duration unknown: no earlier timed run)")
    assert not (tmp_path / "r").exists(), "a dry run writes nothing"


def test_dry_run_says_why_each_earlier_run_cannot_stand_in(tmp_path):
    results, data = tmp_path / "r", str(tmp_path / "d")

    def wanted(key):
        overrides = planned(key).run_overrides(True, data)
        return compose_config(planned(key).exp, overrides[1:], out_dir=results)

    sha, _ = git_state(REPO)
    _fake_run(results, "1-dirty", wanted("temporal_order"), git_sha=sha, git_dirty=True)
    _fake_run(results, "1-other", wanted("structure_fit"), git_sha="0000000")
    _fake_run(results, "1-full", {**wanted("dynamic_slam-kitchen"), "n_seeds": 50}, duration_s=100.0)
    head = _fake_run(results, "1-head", wanted("articulation_estimation"), git_sha=sha, duration_s=3.0)
    done = _reproduce("--dry-run", "--quick", "--results", str(results), "--data-dir", data)
    assert done.returncode == 0, done.stderr
    runs, kept = _lines(done, "run"), _lines(done, "keep")
    assert runs["temporal_order"] == (f"stale: made from a work tree with uncommitted changes (git {sha}) "
                                      "(1-dirty); estimated unknown")
    assert runs["structure_fit"].startswith("stale: git 0000000 is not a commit of this repository (1-other)")
    # a full run never stands in for a quick one; its time, scaled by the seed counts, is the estimate
    assert runs["dynamic_slam-kitchen"] == "stale: config differs from 1-full: n_seeds: 50 → 2; estimated ≈ 4 s"
    changed = ChangeCache(REPO).changed(sha, dependencies_for(REPO, "articulation_estimation",
                                                              "articulation_estimation"))
    if changed:  # uncommitted edits in this work tree: the run at HEAD is stale by them
        assert runs["articulation_estimation"].startswith(f"stale: {len(changed)} file")
    else:
        assert kept == {"articulation_estimation": f"up to date, {head}"}
        assert done.stdout.rstrip().splitlines()[-1].startswith(f"to run: {len(PLAN) - 1} of {len(PLAN)} (estimated ≈ 4 s")


@pytest.mark.parametrize("args, message", [
    (["--jobs", "0"], "error: --jobs: expected an integer ≥ 1, got '0'"),
    (["--jobs", "two"], "error: --jobs: expected an integer ≥ 1, got 'two'"),
    (["--launcher", "nope"], "error: --launcher: no Hydra launcher named 'nope'; expected one of .*basic.*"),
    (["--launcher-arg", "hydra.launcher.partition=x"], "error: --launcher-arg: only with --launcher"),
    (["--launcher", "basic", "--launcher-arg", "partition"], "error: --launcher-arg: expected KEY=VALUE, .*"),
    (["--bogus"], "error: unrecognized arguments: --bogus"),
    (["--results", "{file}"], "error: --results: .* is not a folder"),
    (["--paper-dir", "{tmp}"], "error: --paper-dir: .* holds no report.tex"),
])
def test_bad_arguments_give_one_error_line_and_exit_2(tmp_path, args, message):
    (tmp_path / "file").write_text("x")
    args = [a.format(file=tmp_path / "file", tmp=tmp_path) for a in args]
    done = _reproduce("--dry-run", "--results", str(tmp_path / "r"), *args)
    assert done.returncode == 2
    assert len(done.stderr.splitlines()) == 1 and re.fullmatch(message, done.stderr.strip()), done.stderr
    assert done.stdout == ""


@pytest.mark.slow
def test_quick_build_has_every_run_and_a_second_dry_run_has_nothing_to_do(tmp_path):
    if shutil.which("latexmk") is None or shutil.which("pdftotext") is None:
        pytest.skip("latexmk and pdftotext are needed to build and read the report")
    paper = tmp_path / "paper"
    paper.mkdir()
    for name in ("report.tex", "paper_numbers.csv"):
        shutil.copy2(REPO / "paper" / name, paper / name)
    where = ["--quick", "--results", str(tmp_path / "r"), "--data-dir", str(tmp_path / "d"), "--paper-dir", str(paper)]
    done = _reproduce(*where, "--jobs", "2", timeout=1200)
    assert done.returncode == 0, done.stdout + done.stderr
    started = [line for line in done.stdout.splitlines() if re.match(r"\d\d:\d\d:\d\d start ", line)]
    finished = [line for line in done.stdout.splitlines() if re.match(rf"\d\d:\d\d:\d\d done +\[\d+/{len(PLAN)}\] ", line)]
    assert len(started) == len(finished) == len(PLAN)
    text = " ".join(subprocess.run(["pdftotext", str(paper / "report.pdf"), "-"], capture_output=True, text=True,
                                   check=True).stdout.split())
    assert "Not available" not in text
    assert "Quick build. The runs behind this report used the small seed counts" in text
    again = _reproduce("--dry-run", *where)
    assert again.returncode == 0, again.stderr
    _, dirty = git_state(REPO)
    if dirty:  # runs made from a tree with uncommitted changes cannot count as current
        assert "Not every number in this report comes from the current code" in text
        assert len(_lines(again, "run")) == len(PLAN)
    else:
        assert "Every number in this report comes from the current code" in text
        assert _lines(again, "run") == {} and len(_lines(again, "keep")) == len(PLAN)
        assert again.stdout.rstrip().splitlines()[-1].startswith(f"nothing to run: all {len(PLAN)} runs are up to date")
