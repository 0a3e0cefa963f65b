"""Seeds as units of work on real runs (SPEC 12, 18): jobs=2 gives jobs=1's numbers; a run killed
part-way and continued with resume=true ends with the uninterrupted run's folder; a changed config is
refused; a worker killed from outside stops the run naming its seed.

The runs are dynamic_slam on the small default world (square_centred, two methods, ~1 s a seed); the
killed ones are real processes of ``experiments/run.py``.
"""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from stslam.experiments.runner import execute

from conftest import REPO, compose_config

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="forked workers, /proc")
N_SEEDS = 3
METHODS = "methods=[ekf_slam,a_slam]"  # two of the five: half the time, the same paths through the runner
RUN = ["+exp=dynamic_slam", f"n_seeds={N_SEEDS}", METHODS, "progress=false"]
# The killed-worker run needs seeds left when its first worker is seen: with three seeds of ~0.5 s, a loaded
# machine sometimes finished them all before the kill (the run then ended with 0, not 2).
N_SEEDS_KILLED = 8
RUN_KILLED = ["+exp=dynamic_slam", f"n_seeds={N_SEEDS_KILLED}", METHODS, "progress=false"]
WAIT_S = 120.0  # generous: the machine is shared; a checkpoint normally appears within ~8 s of the start


def _files(folder: Path) -> dict[str, str]:
    """SHA-256 of every file under ``folder`` but config.yaml and version.json (which name the command)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file() and p.name not in ("config.yaml", "version.json")}


def _tree(root: Path) -> dict[str, str]:
    return {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(root.rglob("*"))}


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """The reference: the run with jobs=1, never interrupted."""
    out = tmp_path_factory.mktemp("reference")
    return execute(compose_config("dynamic_slam", [f"n_seeds={N_SEEDS}", METHODS, "jobs=1"], out_dir=out))


def _start(out_dir: Path, *overrides: str, log: Path, run=tuple(RUN)) -> subprocess.Popen:
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONUNBUFFERED="1")
    with log.open("wb") as stderr:
        return subprocess.Popen([sys.executable, str(REPO / "experiments" / "run.py"), *run, f"out_dir={out_dir}",
                                 *overrides], cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=stderr,
                                start_new_session=True)


def _wait_for(process, condition, what: str, log: Path, out_dir: Path):
    """Poll ``condition()`` until true; meanwhile no complete (non-dot) results folder may appear."""
    deadline = time.monotonic() + WAIT_S
    while not (found := condition()):
        parent = out_dir / "dynamic_slam"
        assert not parent.is_dir() or all(p.name.startswith(".") for p in parent.iterdir())
        if process.poll() is not None or time.monotonic() > deadline:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
            pytest.fail(f"{what} did not happen: {log.read_text(errors='replace')[-3000:]}")
        time.sleep(0.05)
    return found


def _checkpoints(out_dir: Path) -> list[Path]:
    return sorted((out_dir / "dynamic_slam").glob(".incomplete-*/.seeds/dynamic_slam-*.pkl"))


def test_jobs_2_gives_the_numbers_of_jobs_1(uninterrupted, tmp_path):
    folder = execute(compose_config("dynamic_slam", [f"n_seeds={N_SEEDS}", METHODS, "jobs=2"], out_dir=tmp_path))
    assert (folder / "metrics.csv").read_bytes() == (uninterrupted / "metrics.csv").read_bytes()
    assert _files(folder) == _files(uninterrupted)  # figures, TUM files and scene.mcap too
    version = json.loads((folder / "version.json").read_text())
    assert version["jobs"] == 2 and version["resumed_seeds"] == 0
    assert [p.name for p in folder.parent.iterdir()] == [folder.name]  # no checkpoint or temporary left


def test_killed_run_resumes_to_the_uninterrupted_folder(uninterrupted, tmp_path):
    out, log = tmp_path / "results", tmp_path / "stderr.txt"
    process = _start(out, "jobs=1", log=log)
    _wait_for(process, lambda: _checkpoints(out), "a first checkpoint", log, out)
    os.killpg(process.pid, signal.SIGKILL)  # the whole job, as a scheduler's pre-emption does
    process.wait()
    parent = out / "dynamic_slam"
    assert [p.name for p in parent.iterdir() if not p.name.startswith(".")] == []
    kept = _checkpoints(out)
    assert 1 <= len(kept) < N_SEEDS

    # Another config is refused, naming the key, and nothing on disk changes.
    before = _tree(out)
    refused = subprocess.run([sys.executable, str(REPO / "experiments" / "run.py"), *RUN, f"out_dir={out}",
                              "world=kitchen", "resume=true"], cwd=REPO, capture_output=True, text=True,
                             env=dict(os.environ, MPLBACKEND="Agg"))
    assert refused.returncode == 2 and "Traceback" not in refused.stderr
    line, = refused.stderr.strip().splitlines()
    assert line.startswith("error: resume: no incomplete dynamic_slam run under ")
    assert "world.name: 'square_centred' → 'kitchen'" in line
    assert _tree(out) == before

    # The same command with resume=true (and other jobs) finishes the run.
    resumed = subprocess.run([sys.executable, str(REPO / "experiments" / "run.py"), *RUN, f"out_dir={out}",
                              "jobs=2", "resume=true"], cwd=REPO, capture_output=True, text=True,
                             env=dict(os.environ, MPLBACKEND="Agg"))
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    assert resumed.stdout.startswith(f"resume: continuing {kept[0].parent.parent}")
    folders = [p for p in parent.iterdir()]
    assert len(folders) == 1 and not folders[0].name.startswith(".")
    assert (folders[0] / "metrics.csv").read_bytes() == (uninterrupted / "metrics.csv").read_bytes()
    assert _files(folders[0]) == _files(uninterrupted)
    assert json.loads((folders[0] / "version.json").read_text())["resumed_seeds"] == len(kept)


def test_a_killed_worker_stops_the_run_naming_its_seed(tmp_path):
    out, log = tmp_path / "results", tmp_path / "stderr.txt"
    process = _start(out, "jobs=2", log=log, run=tuple(RUN_KILLED))

    seen = set()

    def workers():
        """Forked workers: children running the run's own command line (not, say, a git query) and seen at two
        polls in a row. A child forked to run another program carries the parent's command line until its
        exec: killing one instead of a worker lets the run end with 0, as it did once in a full suite."""
        try:
            command = Path(f"/proc/{process.pid}/cmdline").read_bytes()
            children = Path(f"/proc/{process.pid}/task/{process.pid}/children").read_text().split()
            now = [c for c in children if Path(f"/proc/{c}/cmdline").read_bytes() == command]
        except OSError:
            return []
        stable = [c for c in now if c in seen]
        seen.update(now)
        return stable

    victim = int(_wait_for(process, workers, "a worker process", log, out)[0])
    os.kill(victim, signal.SIGKILL)  # as the out-of-memory killer would
    process.wait(timeout=WAIT_S)
    stderr = log.read_text(errors="replace")
    assert process.returncode == 2 and "Traceback" not in stderr
    last = stderr.strip().splitlines()[-1]
    assert "its worker process was killed by signal 9 (SIGKILL: out of memory?)" in last
    assert last.startswith("error: seed ") and int(last.split()[2].rstrip(":")) in range(N_SEEDS_KILLED)
    assert last.endswith(f"out_dir={out} jobs=2 resume=true")
    parent = out / "dynamic_slam"
    assert all(p.name.startswith(".incomplete-") for p in parent.iterdir())
    # The seed beside the killed one finished and is kept; resume=true completes the run.
    resumed = subprocess.run([sys.executable, str(REPO / "experiments" / "run.py"), *RUN_KILLED, f"out_dir={out}",
                              "jobs=2", "resume=true"], cwd=REPO, capture_output=True, text=True,
                             env=dict(os.environ, MPLBACKEND="Agg"))
    assert resumed.returncode == 0, resumed.stderr[-3000:]
    folder, = [p for p in parent.iterdir() if not p.name.startswith(".")]
    reference = execute(compose_config("dynamic_slam", [f"n_seeds={N_SEEDS_KILLED}", METHODS, "jobs=1"],
                                       out_dir=tmp_path / "reference"))
    assert (folder / "metrics.csv").read_bytes() == (reference / "metrics.csv").read_bytes()
    assert json.loads((folder / "version.json").read_text())["resumed_seeds"] >= 1


def test_resume_with_nothing_to_resume_runs_from_scratch_and_says_so(tmp_path, capsys):
    folder = execute(compose_config("structure_fit", ["n_seeds=5", "sweep.n_seeds=0", "resume=true"],
                                    out_dir=tmp_path))
    out = capsys.readouterr().out
    assert out.startswith(f"resume: no incomplete structure_fit run of this config under {tmp_path / 'structure_fit'}; "
                          "running from scratch\n")
    assert json.loads((folder / "version.json").read_text())["resumed_seeds"] == 0
    assert [p.name for p in (tmp_path / "structure_fit").iterdir()] == [folder.name]


def test_a_killed_submitit_job_requeued_with_resume_continues(uninterrupted, tmp_path):
    """The SLURM path, locally: a sweep job (submitit_local) killed part-way, then run again with the same
    overrides, as a requeue after a pre-emption does, continues from its kept seeds."""
    pytest.importorskip("hydra_plugins.hydra_submitit_launcher")
    out, log = tmp_path / "results", tmp_path / "stderr.txt"
    sweep = ["-m", *RUN, f"out_dir={out}", "seed=0", "resume=true", "hydra/launcher=submitit_local"]
    env = dict(os.environ, MPLBACKEND="Agg")
    with log.open("wb") as stderr:
        process = subprocess.Popen([sys.executable, str(REPO / "experiments" / "run.py"), *sweep], cwd=REPO, env=env,
                                   stdout=subprocess.DEVNULL, stderr=stderr, start_new_session=True)
    kept = _wait_for(process, lambda: _checkpoints(out), "a first checkpoint of the job", log, out)
    job_pid = int(kept[0].parent.parent.name.rsplit("-", 1)[1])  # .incomplete-<stamp>-<sha>-<pid>
    os.kill(job_pid, signal.SIGKILL)  # the job alone: the launcher sees it fail
    process.wait(timeout=WAIT_S)
    parent = out / "dynamic_slam"
    assert [p.name for p in parent.iterdir() if not p.name.startswith(".")] == []
    again = subprocess.run([sys.executable, str(REPO / "experiments" / "run.py"), *sweep], cwd=REPO, env=env,
                           capture_output=True, text=True)
    assert again.returncode == 0, again.stderr[-3000:]
    folder, = [p for p in parent.iterdir() if not p.name.startswith(".")]
    assert (folder / "metrics.csv").read_bytes() == (uninterrupted / "metrics.csv").read_bytes()
    assert json.loads((folder / "version.json").read_text())["resumed_seeds"] >= 1
    job_logs = "".join(p.read_text() for p in (out / "multirun").rglob("*_log.out"))
    assert "resume: continuing " in job_logs


@pytest.mark.parametrize("exp, overrides", [
    ("structure_fit", ["n_seeds=1500", "sweep.n_seeds=0"]),  # two units (1000 and 500 Monte Carlo runs)
    ("temporal_order", ["n_seeds=3", "plot_seed=1"]),
    ("articulation_estimation", ["n_seeds=3"]),
    # two short generated recordings (the plotted one's tracks and result cross from a worker)
    ("fridge", ["n_seeds=2", "plot_seed=1", "sequence.n_frames=60", "sequence.width=160", "sequence.height=120",
                "landmarks.min_track_frames=20", "filters.a_slam.common_axis.min_tracks=5"]),
], ids=["structure_fit", "temporal_order", "articulation_estimation", "fridge"])
def test_every_multi_seed_experiment_gives_the_numbers_of_jobs_1_with_jobs_2(tmp_path, exp, overrides):
    data = [f"data_dir={tmp_path / 'data'}"] if exp == "fridge" else []
    folders = {jobs: execute(compose_config(exp, [*overrides, *data, f"jobs={jobs}"], out_dir=tmp_path / str(jobs)))
               for jobs in (2, 1)}  # jobs=2 first: the fridge recordings are made in two workers at once
    assert (folders[2] / "metrics.csv").read_bytes() == (folders[1] / "metrics.csv").read_bytes()
    assert _files(folders[2]) == _files(folders[1])
