"""Nothing lost (SPEC 12, issue 12): a run that is interrupted, killed or fails while
writing leaves no folder that looks complete, and earlier results folders are
never touched.

The interrupted runs are real processes of ``experiments/run.py``: a structure_fit
run of 200,000 Monte Carlo seeds (minutes of work) is signalled once its progress
bar is on stderr and it has kept its first finished seeds, i.e. while it computes.
Finished seeds are kept in a hidden ``.incomplete-…`` folder, for ``resume=true``
(issue 42, SPEC 18): nothing else appears beside the earlier folders.
"""

from __future__ import annotations

import errno
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from matplotlib.figure import Figure

from stslam.errors import ConfigError
from stslam.io.results import complete_runs
from stslam.experiments.runner import execute

REPO = Path(__file__).resolve().parents[2]
LONG_RUN = ["+exp=structure_fit", "n_seeds=200000", "sweep.n_seeds=0", "progress=true"]
STARTUP_LIMIT_S = 60.0  # generous: the machine is shared; a normal start takes ~3 s


def _tree_digest(folder: Path) -> dict[str, str]:
    """SHA-256 of every file under ``folder`` by relative path (names and bytes)."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.fixture
def earlier_run(compose_exp, tmp_path):
    """A complete structure_fit folder written before the run under test, with its digest."""
    folder = execute(compose_exp("structure_fit", "n_seeds=3", "sweep.n_seeds=0"))
    digest = _tree_digest(folder)
    assert {"config.yaml", "version.json", "metrics.csv", "summary.csv"} <= set(digest)
    return tmp_path / "results", folder, digest


def _start_long_run(out_dir: Path, stderr_path: Path) -> subprocess.Popen:
    """Start the long run and return once its progress bar has appeared on stderr."""
    env = dict(os.environ, MPLBACKEND="Agg", PYTHONUNBUFFERED="1")
    with stderr_path.open("wb") as stderr:
        # As a run started from a terminal: SIGINT at its default. A job started in the background
        # by a shell without job control (a CI runner, `cmd &` in a script) inherits SIGINT
        # ignored, and Python then rightly leaves Ctrl-C ignored in the child too.
        process = subprocess.Popen([sys.executable, str(REPO / "experiments" / "run.py"), *LONG_RUN,
                                    f"out_dir={out_dir}"], cwd=REPO, env=env,
                                   stdout=subprocess.DEVNULL, stderr=stderr,
                                   preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + STARTUP_LIMIT_S

    def computing():
        text = stderr_path.read_bytes()
        return (b"it/s]" in text or b"s/it]" in text) and any(out_dir.glob("structure_fit/.incomplete-*/.seeds/*.pkl"))

    while not computing():
        if process.poll() is not None or time.monotonic() > deadline:
            process.kill()
            process.wait()
            pytest.fail(f"the long run did not start computing: {stderr_path.read_text(errors='replace')}")
        time.sleep(0.1)
    return process


@pytest.mark.parametrize("sig, exit_code", [(signal.SIGINT, 130), (signal.SIGTERM, 130),
                                             (signal.SIGKILL, -signal.SIGKILL)],
                         ids=["ctrl-c", "terminate", "kill"])
def test_interrupted_run_leaves_no_complete_folder_and_keeps_earlier_ones(earlier_run, tmp_path, sig, exit_code):
    out_dir, earlier, digest = earlier_run
    entries_before = sorted(p.name for p in (out_dir / "structure_fit").iterdir())
    stderr_path = tmp_path / "stderr.txt"
    process = _start_long_run(out_dir, stderr_path)
    process.send_signal(sig)
    try:
        returncode = process.wait(timeout=30)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
        pytest.fail(f"the run ignored {sig.name} for 30 s; its stderr ends with: "
                    f"{stderr_path.read_text(errors='replace')[-3000:]}")
    stderr = stderr_path.read_text(errors="replace")
    assert returncode == exit_code, stderr[-3000:]
    assert "Traceback" not in stderr
    if sig != signal.SIGKILL:  # a killed process cannot say anything
        lines = [line.split("\r")[-1] for line in stderr.rstrip().splitlines()]
        assert lines[-1] == "interrupted: no results folder was written"
        assert " finished seed(s) are kept in " in lines[-2] and lines[-2].endswith(" resume=true")
    # Only the earlier folder looks complete; beside it only the hidden folder of the finished seeds.
    assert complete_runs(out_dir, "structure_fit") == [earlier]
    entries = sorted(p.name for p in (out_dir / "structure_fit").iterdir())
    kept = [name for name in entries if name not in entries_before]
    assert [name for name in entries if name in entries_before] == entries_before
    assert len(kept) == 1 and kept[0].startswith(".incomplete-")
    assert any((out_dir / "structure_fit" / kept[0] / ".seeds").glob("*.pkl"))
    assert _tree_digest(earlier) == digest


@pytest.mark.parametrize("failure, expected", [
    (OSError(errno.ENOSPC, "No space left on device"),
     (ConfigError, r"^out_dir: cannot write the results folder under .*: No space left on device$")),
    (RuntimeError("renderer crashed"), (RuntimeError, "^renderer crashed$")),
    (KeyboardInterrupt(), (KeyboardInterrupt, "^$")),  # Ctrl-C (or SIGTERM) while writing
], ids=["disk-full", "bug", "ctrl-c"])
def test_failure_while_writing_leaves_no_complete_folder(earlier_run, compose_exp, monkeypatch, failure, expected):
    out_dir, earlier, digest = earlier_run
    entries_before = sorted(p.name for p in (out_dir / "structure_fit").iterdir())

    def failing_savefig(self, *args, **kwargs):
        raise failure

    # Figures are written after config.yaml, version.json and every CSV: a late failure.
    monkeypatch.setattr(Figure, "savefig", failing_savefig)
    error_type, pattern = expected
    with pytest.raises(error_type, match=pattern):
        execute(compose_exp("structure_fit", "n_seeds=3", "sweep.n_seeds=0", "seed=7"))
    assert complete_runs(out_dir, "structure_fit") == [earlier]
    entries = sorted(p.name for p in (out_dir / "structure_fit").iterdir())
    kept = [name for name in entries if name not in entries_before]
    assert len(kept) == 1 and kept[0].startswith(".incomplete-")  # the seeds, kept for resume=true
    assert _tree_digest(earlier) == digest
    # With the failure gone, resume=true writes the folder from the kept seeds.
    monkeypatch.undo()
    folder = execute(compose_exp("structure_fit", "n_seeds=3", "sweep.n_seeds=0", "seed=7", "resume=true"))
    assert json.loads((folder / "version.json").read_text())["resumed_seeds"] == 3
    assert sorted(p.name for p in (out_dir / "structure_fit").iterdir()) == sorted([*entries_before, folder.name])
    assert {"metrics.csv", "summary.csv", "figures"} <= {p.name for p in folder.iterdir()}
    assert not (folder / ".seeds").exists()
