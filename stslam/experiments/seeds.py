"""Seeds as units of work (SPEC 12, 18): one runner of a run's seeds for every experiment.

A driver hands :meth:`SeedRunner.map` a function of the seed index ``k`` (seed ``seed + k``, whose
random generator depends on that seed alone) and gets the results back in seed order, however
they were computed:

- ``jobs`` = 1: one after another in this process; ``jobs`` > 1: in up to ``jobs`` worker
  processes at once, one fresh process (``os.fork``) per unit of work, so a worker's memory is
  returned when its seed ends and one seed's state never reaches another's;
- every finished unit (a seed, or a block of cheap seeds) is kept at once in the run's incomplete
  folder (:class:`stslam.io.checkpoints.RunCheckpoints`); a unit kept there is read back instead
  of computed, which is how ``resume=true`` continues a killed run;
- a worker that dies (a signal: killed, out of memory) or fails stops the run once the units
  still running have finished and been kept: :class:`SeedWorkerDied` names the seed and says how
  to continue; an exception raised in a worker is raised again here, as it would be with
  ``jobs=1`` (with the worker's traceback as a note).

Workers are forked, so ``work`` may be any callable (closures included); what it returns must
pickle. The progress bar counts finished seeds.
"""

from __future__ import annotations

import os
import pickle
import select
import signal
import sys
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field

from stslam.errors import StslamError
from stslam.io.checkpoints import RunCheckpoints
from stslam.progress import counter

_MISSING = object()


class SeedWorkerDied(StslamError):
    """A worker process ended without its seed's result (a signal, e.g. SIGKILL from the OOM killer)."""


def available_cores() -> int:
    """Cores this process may run on (a scheduler's CPU set where the OS says; else all)."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not Linux
        return os.cpu_count() or 1


@dataclass
class SeedRunner:
    """How a run's seeds are computed and kept (see the module docstring).

    ``checkpoints`` is the run's store, or ``make_checkpoints`` makes it (the incomplete folder) at
    the first :meth:`map`; with neither (a driver called directly) nothing is kept and the seeds run
    in this process. ``seed0`` (the base seed) and ``hint`` (the command that continues the run)
    are for messages. ``resumed_seeds``, ``done_seeds``, ``workers_used`` and ``peak_worker_kib``
    count what :meth:`map` did, for the run's report; they are not parameters.
    """

    jobs: int = 1
    checkpoints: RunCheckpoints | None = None
    make_checkpoints: Callable[[], RunCheckpoints] | None = None
    seed0: int = 0
    hint: str = ""
    resumed_seeds: int = field(default=0, init=False)
    done_seeds: int = field(default=0, init=False)
    workers_used: int = field(default=0, init=False)
    peak_worker_kib: int = field(default=0, init=False)
    _labels: set = field(default_factory=set, init=False)

    def map(self, work: Callable[[int], object], n: int, desc: str, enabled: bool = True, block: int = 1) -> list:
        """``[work(0), …, work(n - 1)]``, computed or read back as the module docstring says.

        ``desc`` names the bar and the checkpoints (one call per ``desc`` in a run); ``block``
        seeds make one unit of work (1 unless a seed takes well under a second).
        """
        if desc in self._labels:
            raise ValueError(f"desc: {desc!r} was already mapped in this run")
        self._labels.add(desc)
        if self.checkpoints is None and self.make_checkpoints is not None:
            self.checkpoints = self.make_checkpoints()
        store = self.checkpoints
        units = [(first, min(first + block, n)) for first in range(0, n, block)]
        results = {}
        for first, stop in units:
            kept = store.load(desc, first) if store is not None else _MISSING
            if isinstance(kept, list) and len(kept) == stop - first:
                results[first] = kept
                self.resumed_seeds += stop - first
        self.done_seeds += sum(len(r) for r in results.values())
        pending = [unit for unit in units if unit[0] not in results]
        with counter(desc, n, enabled) as bar:
            bar.update(sum(len(r) for r in results.values()))
            if self.jobs > 1 and store is not None and pending:
                self._in_workers(work, pending, store, desc, bar, results)
            else:
                for first, stop in pending:
                    results[first] = [work(k) for k in range(first, stop)]
                    if store is not None:
                        store.save(desc, first, results[first])
                    self._finished(bar, stop - first)
        return [value for first, _ in units for value in results[first]]

    def _finished(self, bar, n: int) -> None:
        self.done_seeds += n
        bar.update(n)

    def _seeds(self, first: int, stop: int) -> str:
        a, b = self.seed0 + first, self.seed0 + stop - 1
        return f"seed {a}" if a == b else f"seeds {a}–{b}"

    def _in_workers(self, work, pending, store: RunCheckpoints, label: str, bar, results: dict) -> None:
        """Run ``pending`` units in forked workers, at most ``jobs`` at once."""
        queue = list(pending)
        running = {}  # read end of the worker's pipe → (pid, first, stop)
        failure = None
        self.workers_used = max(self.workers_used, min(self.jobs, len(queue)))
        try:
            while running or (queue and failure is None):
                while queue and failure is None and len(running) < self.jobs:
                    first, stop = queue.pop(0)
                    read_end, pid = _fork_worker(work, first, stop, store, label)
                    running[read_end] = (pid, first, stop)
                ready, _, _ = select.select(list(running), [], [])
                for read_end in ready:
                    pid, first, stop = running.pop(read_end)
                    os.close(read_end)
                    _, status, usage = os.wait4(pid, 0)
                    self.peak_worker_kib = max(self.peak_worker_kib, _kib(usage.ru_maxrss))
                    value = store.load(label, first) if os.waitstatus_to_exitcode(status) == 0 else _MISSING
                    if isinstance(value, list) and len(value) == stop - first:
                        results[first] = value
                        self._finished(bar, stop - first)
                        continue
                    error = self._failure(status, store, label, first, stop)
                    failure = failure or error
                    if running:
                        print(f"\n{_first_line(error)}; waiting for the {len(running)} seed(s) still running to "
                              "finish and be kept (Ctrl-C stops at once)", file=sys.stderr)
        except BaseException:
            for read_end, (pid, _, _) in running.items():  # Ctrl-C, SIGTERM: no worker outlives the run
                _kill_and_reap(pid)
                os.close(read_end)
            raise
        if isinstance(failure, SeedWorkerDied):
            raise SeedWorkerDied(f"{failure}; {self.kept_line()}")  # counted now that the others are kept
        if failure is not None:
            raise failure

    def _failure(self, status: int, store: RunCheckpoints, label: str, first: int, stop: int) -> BaseException:
        """The exception that stops the run after unit ``first`` ended without a result."""
        report = store.pop_error(label, first)
        if report is not None and report.get("error") is not None:
            error = report["error"]
            where = f"raised in the worker process of {self._seeds(first, stop)}"
            error.add_note(f"{where}:\n{report.get('traceback', '')}")
            return error
        if report is not None:
            return RuntimeError(f"{self._seeds(first, stop)}: the worker failed: {report.get('text')}\n"
                                f"{report.get('traceback', '')}")
        code = os.waitstatus_to_exitcode(status)
        if code < 0:
            try:
                name = signal.Signals(-code).name
            except ValueError:
                name = "unnamed"
            why = f"was killed by signal {-code} ({name}{': out of memory?' if -code == signal.SIGKILL else ''})"
        else:
            why = f"ended with exit code {code} without its result"
        return SeedWorkerDied(f"{self._seeds(first, stop)}: its worker process {why}")

    def kept_line(self) -> str:
        """Where the finished seeds are and the command that continues the run."""
        where = self.checkpoints.folder if self.checkpoints is not None else "the run's incomplete folder"
        return f"the {self.done_seeds} finished seed(s) are kept in {where}; continue with: {self.hint}"


def _kib(maxrss: int) -> int:
    """ru_maxrss in KiB (macOS reports bytes)."""
    return int(maxrss) // 1024 if sys.platform == "darwin" else int(maxrss)


def _first_line(error: BaseException) -> str:
    return (str(error).splitlines() or [type(error).__name__])[0]


def _fork_worker(work, first: int, stop: int, store: RunCheckpoints, label: str) -> tuple[int, int]:
    """Fork a worker for seeds ``first`` … ``stop - 1``; the read end of a pipe it holds open until it ends."""
    read_end, write_end = os.pipe()
    sys.stdout.flush()
    sys.stderr.flush()
    pid = os.fork()
    if pid == 0:  # the worker: compute, keep the result, leave without running the parent's exit code
        os.close(read_end)
        code = 1
        try:
            _become_worker(store)
            store.save(label, first, [work(k) for k in range(first, stop)])
            code = 0
        except BaseException as error:  # noqa: BLE001 - reported to the main process, which decides
            try:
                store.save_error(label, first, _error_report(error))
            except BaseException:  # noqa: BLE001
                code = 2
        finally:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(code)
    os.close(write_end)
    return read_end, pid


def _become_worker(store: RunCheckpoints) -> None:
    """Signals and locks of a worker: Ctrl-C is the main process's to handle, SIGTERM ends the worker,
    the run's lock stays the main process's, and (Linux) the worker dies with the main process."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    parent = os.getppid()
    store.close()  # this copy only: the main process still holds the lock
    if sys.platform.startswith("linux"):
        import ctypes

        PR_SET_PDEATHSIG = 1
        ctypes.CDLL(None).prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL))
        if os.getppid() != parent:  # the main process ended before the request took effect
            os._exit(1)


def _error_report(error: BaseException) -> dict:
    text = "".join(traceback.format_exception(error))
    try:
        pickle.loads(pickle.dumps(error))  # both ways: an exception's own __init__ may not take its args
        kept = error
    except Exception:  # noqa: BLE001 - reported as text; a user's error keeps its one line
        kept = StslamError(str(error)) if isinstance(error, StslamError) else None
    return {"error": kept, "text": f"{type(error).__name__}: {error}", "traceback": text}


def _kill_and_reap(pid: int) -> None:
    try:
        os.kill(pid, signal.SIGKILL)
    except ProcessLookupError:
        pass
    try:
        os.waitpid(pid, 0)
    except ChildProcessError:
        pass
