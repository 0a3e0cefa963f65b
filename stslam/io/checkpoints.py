"""Finished seeds kept inside a run's incomplete folder, so that a killed run can go on (SPEC 12, 18).

A run's ``<out_dir>/<exp>/.incomplete-…`` folder (:mod:`stslam.io.results`) holds, while the
run computes, a hidden ``.seeds/`` folder:

- ``run.json``: the experiment, its resolved configuration, the git commit and when the run began;
- ``<label>-<k>.pkl``: the result of the unit of work whose first seed index is ``k`` (one seed, or
  a block of cheap ones), written to a temporary name and renamed, so a file there is whole;
- ``<label>-<k>.error``: why that unit failed in a worker process (read back by the main process);
- ``lock``: held (``flock``) by the process running the seeds, so two processes never continue
  the same run.

``.seeds/`` is removed before the folder is renamed to its final name, so a complete results folder
has exactly the files of a run that was never interrupted. A checkpoint is a pickle of the driver's
own per-seed result: only ever read back from a folder this project wrote.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
import pickle
import re
import shutil
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - not POSIX: no lock, a run is still checkpointed
    fcntl = None

STATE_DIR = ".seeds"
INCOMPLETE_PREFIX = ".incomplete-"
_MISSING = object()


class RunLocked(Exception):
    """Another live process holds the run's lock."""


def _atomic_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and an atomic rename."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        tmp.write_bytes(data)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def _unit_name(label: str, first: int, suffix: str) -> str:
    return f"{re.sub(r'[^A-Za-z0-9_]+', '_', label)}-{first}{suffix}"


class RunCheckpoints:
    """The checkpoints of one incomplete run (its folder ``folder``), holding the run's lock.

    Make one with :meth:`create` (a new run) or :meth:`open` (continuing one); :meth:`close`
    releases the lock and :meth:`discard` removes the checkpoints once the results are written.
    """

    def __init__(self, folder: Path, lock_fd: int | None):
        self.folder = Path(folder)
        self.state = self.folder / STATE_DIR
        self.lock_fd = lock_fd

    @classmethod
    def create(cls, folder: Path, meta: dict) -> RunCheckpoints:
        """A new incomplete folder ``folder`` (its parents made as needed) with ``run.json`` = ``meta``."""
        folder = Path(folder)
        folder.parent.mkdir(parents=True, exist_ok=True)
        folder.mkdir()
        (folder / STATE_DIR).mkdir()
        run = cls(folder, _lock(folder / STATE_DIR / "lock"))
        _atomic_bytes(run.state / "run.json", (json.dumps(meta, indent=1) + "\n").encode())
        return run

    @classmethod
    def open(cls, folder: Path) -> RunCheckpoints:
        """The checkpoints of an existing incomplete folder; RunLocked when a live process holds them."""
        return cls(Path(folder), _lock(Path(folder) / STATE_DIR / "lock"))

    def save(self, label: str, first: int, value) -> None:
        """Keep ``value`` as the result of unit ``first`` of ``label`` (atomically)."""
        _atomic_bytes(self.state / _unit_name(label, first, ".pkl"), pickle.dumps(value, protocol=5))

    def load(self, label: str, first: int, default=_MISSING):
        """The kept result of unit ``first`` of ``label``; ``default`` when there is none or it is unreadable."""
        path = self.state / _unit_name(label, first, ".pkl")
        try:
            return pickle.loads(path.read_bytes())
        except FileNotFoundError:
            return default
        except (pickle.UnpicklingError, EOFError, AttributeError, ImportError, ValueError, TypeError):
            return default  # damaged (a power cut before the data reached the disk): computed again

    def save_error(self, label: str, first: int, error: dict) -> None:
        _atomic_bytes(self.state / _unit_name(label, first, ".error"), pickle.dumps(error, protocol=5))

    def pop_error(self, label: str, first: int) -> dict | None:
        """The error a worker left for unit ``first`` (removed from the folder), or None."""
        path = self.state / _unit_name(label, first, ".error")
        try:
            data = path.read_bytes()
        except FileNotFoundError:
            return None
        path.unlink(missing_ok=True)
        try:
            return pickle.loads(data)
        except Exception:  # noqa: BLE001 - an unreadable report still says the unit failed
            return {"text": "the worker's error report could not be read"}

    def n_units(self) -> int:
        """How many units of work are kept."""
        return sum(1 for _ in self.state.glob("*.pkl")) if self.state.is_dir() else 0

    def close(self) -> None:
        """Release the lock (the checkpoints stay)."""
        if self.lock_fd is not None:
            os.close(self.lock_fd)
            self.lock_fd = None

    def discard(self) -> None:
        """Remove the checkpoints and release the lock: the folder holds only the results."""
        shutil.rmtree(self.state, ignore_errors=True)
        self.close()


def _lock(path: Path) -> int | None:
    """Open ``path`` and take an exclusive lock on it without waiting; RunLocked if it is held."""
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    if fcntl is None:  # pragma: no cover
        return fd
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        raise RunLocked(str(path)) from None
    return fd


def run_meta(exp: str, config: dict, git_sha: str, now: _dt.datetime | None = None) -> dict:
    """``run.json``'s contents."""
    return {"exp": exp, "config": config, "git_sha": git_sha,
            "created": (now or _dt.datetime.now()).isoformat(timespec="microseconds")}


def incomplete_runs(parent: Path) -> list[tuple[Path, dict]]:
    """Incomplete folders under ``parent`` that can be continued (they have ``run.json``), newest first."""
    if not Path(parent).is_dir():
        return []
    out = []
    for folder in Path(parent).iterdir():
        if not (folder.name.startswith(INCOMPLETE_PREFIX) and folder.is_dir()):
            continue
        try:
            meta = json.loads((folder / STATE_DIR / "run.json").read_text())
        except (OSError, ValueError):
            continue  # a run of an older version, or killed while it was being created
        if isinstance(meta, dict) and isinstance(meta.get("config"), dict):
            out.append((folder, meta))
    return sorted(out, key=lambda item: (str(item[1].get("created", "")), item[0].name), reverse=True)
