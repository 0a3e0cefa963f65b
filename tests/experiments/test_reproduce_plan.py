"""The plan of experiments/reproduce.py against paper/report.tex, and its pure helpers."""

from __future__ import annotations

import importlib.util
import re
import subprocess
import sys
from pathlib import Path

import pytest

from stslam.experiments import EXPERIMENTS
from stslam.experiments.code_deps import experiment_dependencies
from stslam.experiments.reproduce import (PLAN, CodeOrigin, RunRecord, config_differences, estimate_seconds,
                                          estimate_text, format_duration, judge, planned, total_estimate)
from stslam.render.report_provenance import provenance_macros, provenance_text

from conftest import REPO, compose_config


def _report_module():
    spec = importlib.util.spec_from_file_location("stslam_report_script", REPO / "experiments" / "report.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


report = _report_module()


def _report_commands() -> dict[str, list[str]]:
    """key → overrides of every ``\\missingrun{key}{python experiments/run.py …}`` in report.tex."""
    text = (REPO / "paper" / "report.tex").read_text()
    out = {}
    for key, command in re.findall(r"\\missingrun\{([^}<#]+)\}\{python experiments/run\.py ([^}]*)\}", text):
        args = command.replace("\\_", "_").replace("'", "").split()
        out[key] = [a.replace("tracks=", "tracks.glob=", 1) if a.startswith("tracks=") else a for a in args]
    return out


def _compose(overrides: list[str]) -> dict:
    exp = overrides[0].removeprefix("+exp=")
    return compose_config(exp, overrides[1:])


def test_the_plan_is_every_run_the_report_names():
    commands = _report_commands()
    assert len(commands) == len(PLAN) == len({e.key for e in PLAN})
    assert set(commands) == {e.key for e in PLAN}
    assert {e.exp for e in PLAN} == set(EXPERIMENTS)


@pytest.mark.parametrize("entry", PLAN, ids=lambda e: e.key)
def test_each_planned_run_composes_the_reports_command(entry):
    full = _compose(entry.run_overrides(False, "data"))
    assert full == _compose(_report_commands()[entry.key])  # the configs' defaults: the report's seed counts
    variant = report.variant_of(full)
    assert (entry.exp if not variant else f"{entry.exp}-{variant}") == entry.key
    quick = _compose(entry.run_overrides(True, "data"))
    assert report.variant_of(quick) == variant
    assert config_differences(quick, full), "a quick run must never stand in for a full one"
    assert quick.get("n_seeds", 1) <= full.get("n_seeds", 1)


def test_quick_overrides_replace_those_of_the_same_key_and_data_goes_where_asked():
    entry = planned("classify_tracks")
    assert entry.run_overrides(True, "/d") == ["+exp=classify_tracks", "tracks.glob=/d/tracks/track_00*.txt"]
    assert entry.run_overrides(False, "/d") == ["+exp=classify_tracks", "tracks.glob=/d/tracks/*.txt"]
    assert entry.data.argv("/d") == ["experiments/make_tracks.py", "out=/d/tracks", "n=100", "seed=0"]
    assert planned("fridge").run_overrides(True, "/d") == ["+exp=fridge", "data_dir=/d", "n_seeds=1"]
    assert planned("no-such-key") is None


def test_static_dependencies_hold_every_module_an_import_loads():
    """The ast reading misses nothing that importing the experiment (and the runner) loads."""
    for exp in EXPERIMENTS:
        code = (f"import sys, stslam.experiments.runner, stslam.experiments.{exp}\n"
                "print('\\n'.join(sorted(m.__file__ for n, m in list(sys.modules.items())\n"
                "      if n.split('.')[0] == 'stslam' and getattr(m, '__file__', None))))")
        done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, check=True,
                              env={"PYTHONPATH": str(REPO), "MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"})
        loaded = {Path(p).resolve().relative_to(REPO).as_posix() for p in done.stdout.split()}
        assert loaded <= set(experiment_dependencies(REPO, exp)), exp


def test_config_differences_name_the_key_and_both_values():
    old = {"n_seeds": 2, "out_dir": "a", "progress": True, "data_dir": "x", "sensor": {"sigma": 0.04}}
    new = {"n_seeds": 50, "out_dir": "b", "progress": False, "data_dir": "y", "sensor": {"sigma": 0.04, "fov": "cone"}}
    assert config_differences(old, new) == ["n_seeds: 2 → 50", "sensor.fov: (absent) → 'cone'"]
    assert config_differences(new, new) == []


def _run(name: str, config: dict, duration=None, sha="abc1234") -> RunRecord:
    return RunRecord(Path(name), config, {"git_sha": sha, "git_dirty": False, "duration_s": duration})


def test_judge_missing_config_and_newest_current_run():
    wanted = {"exp_name": "e", "n_seeds": 50}
    assert judge("k", wanted, [], lambda r: None).reason == "missing: no complete run"
    quick = _run("1-quick", {"exp_name": "e", "n_seeds": 2})
    stale = judge("k", wanted, [quick], lambda r: None)
    assert stale.todo and stale.reason == "stale: config differs from 1-quick: n_seeds: 2 → 50"
    full_a, full_b = _run("2-full", wanted), _run("3-full", wanted)
    kept = judge("k", wanted, [quick, full_a, full_b], lambda r: None)
    assert not kept.todo and kept.record is full_b
    by_code = judge("k", wanted, [full_a], lambda r: "code moved on")
    assert by_code.todo and by_code.reason == "stale: code moved on (2-full)"


def test_estimates_from_earlier_durations():
    wanted = {"exp_name": "e", "n_seeds": 50, "world": "w"}
    assert estimate_seconds(wanted, [_run("a", wanted)]) is None  # no duration recorded
    assert estimate_seconds(wanted, [_run("a", {**wanted, "n_seeds": 5}, 4.0)]) == pytest.approx(40.0)
    assert estimate_seconds(wanted, [_run("a", {**wanted, "n_seeds": 5}, 4.0), _run("b", wanted, 30.0)]) == 30.0
    assert estimate_seconds(wanted, [_run("a", {**wanted, "world": "v", "n_seeds": 5}, 4.0)]) is None
    assert [format_duration(s) for s in (None, 0.2, 45, 200, 7500)] == ["unknown", "< 1 s", "45 s",
                                                                        "3 min 20 s", "2 h 05 min"]
    assert estimate_text(200) == "≈ 3 min 20 s" and estimate_text(None) == "unknown"
    assert total_estimate([None]) == "duration unknown: no earlier timed run"
    assert total_estimate([60, None, 60]).startswith("estimated ≈ 2 min 00 s from earlier runs")
    assert total_estimate([60, None, 60]).endswith("; 1 run of unknown duration")


def test_title_page_note():
    current = [CodeOrigin("a_key", "abc1234", True, None), CodeOrigin("b", "0ff1ce0", False, None)]
    text = provenance_text(current, "abc1234", False)
    assert text == ("Every number in this report comes from the current code (git \\texttt{abc1234}): 1 of its 2 "
                    "runs were made at this commit and 1 at earlier commits, all from clean trees, and no file "
                    "they depend on has changed since.")
    assert provenance_text(current[:1], "abc1234", False).endswith(": its run was made at this commit from a "
                                                                   "clean tree.")
    assert provenance_text(current[1:] * 3, "abc1234", False).endswith(
        ": its 3 runs were made from clean trees at earlier commits, and no file they depend on has changed since.")
    stale = current + [CodeOrigin("c", "0ff1ce0", False, "made from a work tree with uncommitted changes"),
                       CodeOrigin("d_e", "0ff1ce0", False, "made from a work tree with uncommitted changes")]
    text = provenance_text(stale, "abc1234", True)
    assert text.startswith("Not every number in this report comes from the current code (git \\texttt{abc1234}, "
                           "with uncommitted changes). 2 of its 4 runs were made from other code: ")
    assert "\\texttt{c}, \\texttt{d\\_e} (made from a work tree with uncommitted changes)." in text
    assert "Quick build" in provenance_macros(stale, "abc1234", False, True)
    assert "\\csname reportquick\\endcsname{}" in provenance_macros(stale, "abc1234", False, False)
