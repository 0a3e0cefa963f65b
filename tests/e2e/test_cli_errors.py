"""Bad command lines end in one line (SPEC 12, issue 12).

Each case runs ``python experiments/run.py`` in its own process, as a user
would, and checks: exit code 2, stderr exactly one line ``error: …`` naming the
parameter or file (and line) and what was expected, no traceback, and nothing
created under ``out_dir``. The processes run two at a time (the machine's two
cores) in one module fixture.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pandas as pd
import pytest

from stslam.io.results import complete_runs
from stslam.io.track_files import format_track, write_track_file
from stslam.sim.track_generator import generate_tracks

REPO = Path(__file__).resolve().parents[2]

# id → (arguments, full-line pattern of stderr). "{tmp}" is the fixture's folder of input files.
CASES = {
    "unknown experiment": (["+exp=nope"],
                           r"error: exp: no config named 'nope'; expected one of .*structure_fit.*"),
    "no experiment": (["n_seeds=2"],
                      r"error: exp: no experiment chosen; add \+exp=<name> with one of structure_fit, .*"),
    "unknown key": (["+exp=structure_fit", "bogus=1"],
                    r"error: bogus: no such parameter in the configuration"),
    "unknown world": (["+exp=dynamic_slam", "world=nope"],
                      r"error: world: no config named 'nope'; expected one of kitchen, kitchen_points, paper_square, "
                      r"square_centred"),
    "n_seeds not a number": (["+exp=structure_fit", "n_seeds=abc"],
                             r"error: n_seeds: expected an integer, got 'abc'"),
    "negative seed": (["+exp=structure_fit", "seed=-1"],
                      r"error: seed: expected an integer ≥ 0, got -1"),
    "progress not a bool": (["+exp=structure_fit", "progress=maybe"],
                            r"error: progress: expected true or false, got 'maybe'"),
    "n_samples 2": (["+exp=structure_fit", "protocol=fair", "n_samples=2"],
                    r"error: n_samples: expected an integer ≥ 3, got 2"),
    "negative arc": (["+exp=structure_fit", "protocol=fair", "arc_deg=-5"],
                     r"error: arc_deg: expected a number > 0.0 and ≤ 360.0, got -5.0"),
    "negative sigma": (["+exp=structure_fit", "noise_sigma=-0.1"],
                       r"error: noise_sigma: expected a number > 0.0, got -0.1"),
    "unknown protocol": (["+exp=structure_fit", "protocol=best"],
                         r"error: protocol: expected one of paper, fair; got 'best'"),
    "negative order": (["+exp=temporal_order", "orders=[-1]"],
                       r"error: orders\[0\]: expected an integer ≥ 0, got -1"),
    "k_ahead zero": (["+exp=temporal_order", "k_ahead=0"],
                     r"error: k_ahead: expected an integer ≥ 1, got 0"),
    "dt zero": (["+exp=temporal_order", "dt=0"],
                r"error: dt: expected a number > 0, got 0.0"),
    "missing trace file": (["+exp=temporal_order", "trace.csv={tmp}/missing.csv"],
                           r"error: {tmp}/missing.csv: cannot read the file: No such file or directory"),
    "malformed trace file": (["+exp=temporal_order", "trace.csv={tmp}/bad.csv"],
                             r"error: {tmp}/bad.csv:4: column 'angle': expected a number, got 'open'"),
    "out_dir is a file": (["+exp=structure_fit", "out_dir={tmp}/a_file"],
                          r"error: out_dir: {tmp}/a_file is not a folder; expected a folder for the results"),
    "unclosed list": (["+exp=structure_fit", "n_seeds=[1,2"],
                      r"error: override 'n_seeds=\[1,2': cannot parse it \(no viable alternative at input "
                      r"'\[1,2'\); expected key=value"),
    "unclosed quote": (["+exp=structure_fit", "n_seeds='3"],
                       r"error: override \"n_seeds='3\": cannot parse it.*; expected key=value"),
    "no equals sign": (["+exp=structure_fit", "n_seeds"],
                       r"error: override 'n_seeds': cannot parse it \(missing EQUAL at '<EOF>'\); "
                       r"expected key=value"),
    "no key": (["+exp=structure_fit", "=3"],
               r"error: override '=3': expected key=value with a key before '='"),
    "sweep without -m": (["+exp=structure_fit", "n_seeds=1,2"],
                         r"error: n_seeds: '1,2' is a sweep of several values; add -m to run one job per "
                         r"value \(a list is written \[a,b\], a string with commas is quoted\)"),
    "multirun unknown key": (["-m", "+exp=structure_fit", "n_seeds=2,3", "bogus=1,2"],
                             r"error: bogus: no such parameter in the configuration"),
    "multirun unknown world in one job": (["-m", "+exp=dynamic_slam", "world=kitchen,nope"],
                                          r"error: world: no config named 'nope'; expected one of .*"),
    # Values the experiments check at the start of run() (SPEC 12): before any simulation or file.
    "slam negative sensor sigma": (["+exp=dynamic_slam", "sensor.sigma=-0.1"],
                                   r"error: sensor\.sigma: expected a number > 0\.0, got -0\.1"),
    "slam tau above 1": (["+exp=dynamic_slam", "tau=1.5"],
                         r"error: tau: expected a number > 0\.0 and < 1\.0, got 1\.5"),
    "slam tau zero": (["+exp=dynamic_slam", "tau=0"],
                      r"error: tau: expected a number > 0\.0 and < 1\.0, got 0\.0"),
    "slam no seeds": (["+exp=dynamic_slam", "n_seeds=0"],
                      r"error: n_seeds: expected an integer ≥ 1, got 0"),
    "slam motion noise order 3": (["+exp=dynamic_slam", "motion_noise_order=3"],
                                  r"error: motion_noise_order: expected an integer ≥ 1 and ≤ 2, got 3"),
    "slam update iterations 0": (["+exp=dynamic_slam", "update_iterations=0"],
                                 r"error: update_iterations: expected an integer ≥ 1 and ≤ 20, got 0"),
    "slam unknown method": (["+exp=dynamic_slam", "methods=[nope]"],
                            r"error: methods\[0\]: expected one of ekf_slam, dyn_slam, .*oracle; got 'nope'"),
    "selection n_min 2": (["+exp=articulation_estimation", "selection.n_min=2"],
                          r"error: selection\.n_min: expected an integer ≥ 3, got 2"),
    "selection tau above 1": (["+exp=articulation_estimation", "selection.tau=1.5"],
                              r"error: selection\.tau: expected a number > 0\.0 and < 1\.0, got 1\.5"),
    "marker video values not given": (["+exp=marker_video", "video=clip.mp4"],
                                      r"error: calib, marker_dictionary, marker_length: not set; give each on the "
                                      r"command line, e\.g\. calib=<value>"),
    "no track file matches": (["+exp=classify_tracks", "tracks=/nonexistent/*.txt"],
                              r"error: tracks\.glob: no file matches '/nonexistent/\*\.txt'"),
}


def _run(args: list[str], out_dir: Path) -> subprocess.CompletedProcess:
    """``run.py`` with ``args``; ``out_dir`` comes first so that a case can override it."""
    env = dict(os.environ, MPLBACKEND="Agg")
    return subprocess.run([sys.executable, str(REPO / "experiments" / "run.py"), f"out_dir={out_dir}",
                           "progress=false", *args], cwd=REPO, env=env, capture_output=True, text=True,
                          timeout=300)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("cli_inputs")
    (folder / "bad.csv").write_text("t,angle\n0,0.6\n1,0.7\n2,open\n3,0.9\n")
    (folder / "a_file").write_text("not a folder\n")
    # A glob with one good and one bad track file (SPEC 10): the run completes, the bad file is reported.
    track = generate_tracks(1, seed=3)[0]
    write_track_file(folder / "tracks" / "good.txt", format_track(track.points_world, None, track.metadata()))
    write_track_file(folder / "tracks" / "bad.txt", "0 0 0\n1 1 1\n2 2 nan\n3 3 3\n")
    return folder


@pytest.fixture(scope="module")
def outcomes(inputs, tmp_path_factory):
    """id → (completed process, its out_dir), every case run once, two at a time."""
    root = tmp_path_factory.mktemp("cli_out")

    def one(item):
        case_id, (args, _) = item
        out_dir = root / re.sub(r"\W+", "_", case_id)
        return case_id, (_run([a.replace("{tmp}", str(inputs)) for a in args], out_dir), out_dir)

    with ThreadPoolExecutor(max_workers=2) as pool:
        return dict(pool.map(one, CASES.items()))


@pytest.mark.parametrize("case_id", list(CASES))
def test_bad_command_line_fails_in_one_line(case_id, outcomes, inputs):
    process, out_dir = outcomes[case_id]
    pattern = CASES[case_id][1].replace("{tmp}", re.escape(str(inputs)))
    assert "Traceback" not in process.stderr
    assert process.returncode == 2, process.stderr
    assert process.stderr.endswith("\n") and process.stderr.count("\n") == 1, process.stderr
    assert re.fullmatch(pattern, process.stderr.rstrip("\n")), process.stderr
    assert not out_dir.exists()  # nothing written: not even an empty out_dir or multirun folder


def test_multirun_stops_at_the_job_with_a_bad_value(tmp_path):
    """Values an experiment checks itself fail in their job: jobs before it are complete,
    the sweep stops there (later jobs do not run) and the exit code is 2."""
    process = _run(["-m", "+exp=structure_fit", "sweep.n_seeds=0", "n_seeds=2,abc,3"], tmp_path)
    assert "Traceback" not in process.stderr
    assert process.returncode == 2
    assert process.stderr == "error: n_seeds: expected an integer, got 'abc'\n"
    assert "#1 : " in process.stdout and "#2 : " not in process.stdout  # Hydra's job log is on stdout
    (folder,) = complete_runs(tmp_path, "structure_fit")
    assert "n_seeds: 2\n" in (folder / "config.yaml").read_text()


def test_bad_track_file_in_a_glob_is_reported_and_the_run_completes(inputs, tmp_path):
    """SPEC 10: a bad file is named with its line on stdout and in errors.csv; the good one is classified."""
    process = _run(["+exp=classify_tracks", f"tracks={inputs}/tracks/*.txt"], tmp_path)
    assert "Traceback" not in process.stderr
    assert process.returncode == 0, process.stderr
    bad = inputs / "tracks" / "bad.txt"
    message = f"{bad}:3: values must be finite (found NaN or infinity)"
    assert f"error: {message}\n" in process.stdout
    (folder,) = complete_runs(tmp_path, "classify_tracks")
    errors = pd.read_csv(folder / "errors.csv")
    assert errors.to_dict("records") == [{"file": str(bad), "line": 3,
                                          "problem": "values must be finite (found NaN or infinity)",
                                          "message": message}]
    metrics = pd.read_csv(folder / "metrics.csv")
    assert metrics["file"].tolist() == [str(inputs / "tracks" / "good.txt")]
