"""Make every run the report uses that is missing or stale, then build ``paper/report.pdf``.

    python experiments/reproduce.py                    # the seed counts the report states
    python experiments/reproduce.py --dry-run          # what would run and why, with time estimates
    python experiments/reproduce.py --quick            # small seed counts: CI, a first look
    python experiments/reproduce.py --jobs 2           # independent runs in parallel on this machine
    python experiments/reproduce.py --launcher submitit_slurm --launcher-arg hydra.launcher.partition=<p>
    python experiments/reproduce.py --results /tmp/results --data-dir /tmp/data --paper-dir /tmp/paper

The runs and the rule deciding when an earlier run stands in for one are
``stslam.experiments.reproduce`` (PLAN, judge); this script composes each run's
configuration with Hydra, starts ``experiments/run.py`` for each run to make
(logs in ``<results>/reproduce-logs/<stamp>/``) and calls ``experiments/report.py``
on the runs chosen.
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import shlex
import signal
import subprocess
import sys
import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import yaml
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

import report  # experiments/report.py, beside this script
from stslam.experiments.code_deps import experiment_dependencies
from stslam.experiments.reproduce import (PLAN, PlannedRun, RunRecord, Status, cached_data_note, code_reason,
                                          config_differences, estimate_seconds, estimate_text, format_duration,
                                          judge, total_estimate)
from stslam.io.git_tree import ChangeCache
from stslam.io.results import complete_runs, git_state

REPO = Path(__file__).resolve().parent.parent
CONF = REPO / "conf"
RUN_PY = REPO / "experiments" / "run.py"


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line, exit 2, like every other entry point
        print(f"error: {message}", file=sys.stderr)
        sys.exit(2)


class UsageError(Exception):
    """A bad argument: printed as one ``error:`` line, exit 2."""


def _parse(argv: list[str] | None) -> argparse.Namespace:
    parser = _Parser(description="Make the missing or stale runs of the report, then build it.")
    parser.add_argument("--dry-run", action="store_true", help="list what would run and why; run nothing")
    parser.add_argument("--quick", action="store_true", help="small seed counts (said on the title page)")
    parser.add_argument("--jobs", default=None, help="runs at once (default 1; with --launcher all)")
    parser.add_argument("--launcher", default=None, help="Hydra launcher for the runs (-m hydra/launcher=…)")
    parser.add_argument("--launcher-arg", action="append", default=[], metavar="KEY=VALUE",
                        help="extra override for launched runs, e.g. hydra.launcher.partition=<p> (repeatable)")
    parser.add_argument("--results", type=Path, default=Path("results"), help="root of results (default results)")
    parser.add_argument("--data-dir", default="data",
                        help="where generated inputs go, relative to the repository (default data)")
    parser.add_argument("--paper-dir", type=Path, default=report.PAPER, help="report folder (default paper/)")
    parser.add_argument("--no-pdf", action="store_true", help="write <paper-dir>/generated/ only")
    args = parser.parse_args(argv)
    args.results = args.results.resolve()  # the runs start in the repository, this script anywhere
    if args.jobs is not None:
        if not str(args.jobs).isdigit() or int(args.jobs) < 1:
            raise UsageError(f"--jobs: expected an integer ≥ 1, got {args.jobs!r}")
        args.jobs = int(args.jobs)
    if args.results.exists() and not args.results.is_dir():
        raise UsageError(f"--results: {args.results} is not a folder")
    if not (args.paper_dir / "report.tex").is_file():
        raise UsageError(f"--paper-dir: {args.paper_dir} holds no report.tex")
    if args.launcher_arg and not args.launcher:
        raise UsageError("--launcher-arg: only with --launcher")
    for item in args.launcher_arg:
        if "=" not in item:
            raise UsageError(f"--launcher-arg: expected KEY=VALUE, got {item!r}")
    return args


def _compose(overrides_by_key: dict[str, list[str]], launcher: str | None) -> dict[str, dict]:
    """Resolved config per key, as ``experiments/run.py`` would write it; checks the launcher name."""
    out = {}
    with warnings.catch_warnings(), initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        warnings.simplefilter("ignore")
        if launcher is not None:
            try:
                compose("config", overrides=[f"hydra/launcher={launcher}"], return_hydra_config=True)
            except Exception as error:  # noqa: BLE001 - Hydra's errors for a missing option vary
                listed = str(error).partition("Available options")[2].partition("Config search path")[0]
                names = ", ".join(line.strip() for line in listed.splitlines()[1:] if line.strip())
                raise UsageError(f"--launcher: no Hydra launcher named {launcher!r}"
                                 + (f"; expected one of {names}" if names else "")) from None
        for key, overrides in overrides_by_key.items():
            cfg = compose("config", overrides=overrides)
            out[key] = OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True)
    return out


def _records(results: Path, experiments: set[str]) -> dict[str, list[RunRecord]]:
    """Complete runs under ``results`` by report key, oldest first; unreadable folders are skipped."""
    by_key: dict[str, list[RunRecord]] = {}
    for exp in sorted(experiments):
        for folder in complete_runs(results, exp):
            try:
                config = yaml.safe_load((folder / "config.yaml").read_text())
                version = json.loads((folder / "version.json").read_text())
            except (OSError, ValueError, yaml.YAMLError) as error:
                print(f"warning: {folder}: not readable ({error}); ignored", file=sys.stderr)
                continue
            if not isinstance(config, dict) or not isinstance(version, dict):
                continue
            variant = report.variant_of(config)
            by_key.setdefault(exp if not variant else f"{exp}-{variant}", []).append(
                RunRecord(folder, config, version))
    return by_key


def _command(entry: PlannedRun, args, stamp: str) -> list[str]:
    """The ``experiments/run.py`` command line of a planned run."""
    overrides = entry.run_overrides(args.quick, args.data_dir) + [f"out_dir={args.results}", "progress=false"]
    if args.launcher is None:
        return [sys.executable, str(RUN_PY), *overrides]
    sweep_dir = args.results / "multirun" / f"reproduce-{stamp}-{entry.key}"
    return [sys.executable, str(RUN_PY), "-m", f"hydra/launcher={args.launcher}", f"hydra.sweep.dir={sweep_dir}",
            *overrides, *args.launcher_arg]


def _shown(command: list[str]) -> str:
    return shlex.join(["python", os.path.relpath(command[1], REPO), *command[2:]])


class Runner:
    """Runs the planned commands as subprocesses, at most ``jobs`` at once, printing one line per start and end."""

    def __init__(self, log_dir: Path, total: int):
        self.log_dir = log_dir
        self.total = total
        self._lock = threading.Lock()
        self._processes: set[subprocess.Popen] = set()
        self._stopped = False
        self._env = dict(os.environ, PYTHONPATH=os.pathsep.join(
            [str(REPO), *filter(None, [os.environ.get("PYTHONPATH")])]))
        self._env.setdefault("MPLBACKEND", "Agg")

    def _say(self, text: str) -> None:
        with self._lock:
            print(f"{dt.datetime.now():%H:%M:%S} {text}", flush=True)

    def _call(self, argv: list[str], log) -> int:
        with self._lock:
            if self._stopped:
                return -15
            process = subprocess.Popen(argv, cwd=REPO, env=self._env, stdout=log, stderr=subprocess.STDOUT)
            self._processes.add(process)
        try:
            return process.wait()
        finally:
            with self._lock:
                self._processes.discard(process)

    def run(self, number: int, entry: PlannedRun, command: list[str], data_argv: list[str] | None,
            find_folder) -> tuple[str, Path | None]:
        """Run one planned entry (its data step first); returns (key, new results folder or None)."""
        log_path = self.log_dir / f"{entry.key}.log"
        tag = f"[{number}/{self.total}] {entry.key}"
        started = time.monotonic()
        self._say(f"start  {tag}: log {log_path}")
        with log_path.open("w") as log:
            rc = 0
            if data_argv is not None:
                log.write(f"$ {shlex.join(data_argv)}\n")
                log.flush()
                rc = self._call([sys.executable, str(REPO / data_argv[0]), *data_argv[1:]], log)
            if rc == 0:
                log.write(f"$ {_shown(command)}\n")
                log.flush()
                rc = self._call(command, log)
        took = format_duration(time.monotonic() - started)
        folder = find_folder(entry) if rc == 0 else None
        if folder is None:
            lines = [line for line in log_path.read_text(errors="replace").splitlines() if line.strip()]
            why = lines[-1] if lines else "no output"
            self._say(f"failed {tag} after {took} (exit {rc}): {why}; log {log_path}")
        else:
            self._say(f"done   {tag} in {took}: {folder}")
        return entry.key, folder

    def stop(self) -> None:
        """End the runs still going (SIGTERM: they remove their temporaries)."""
        with self._lock:
            self._stopped = True
            for process in self._processes:
                process.terminate()


def _plan_text(args, statuses, wanted, records, commands, data_steps, sha, dirty) -> tuple[list[str], list[str]]:
    seeds = "quick seed counts (--quick)" if args.quick else "the seed counts the report states"
    lines = [f"plan: {len(PLAN)} runs for the report at {seeds}; results under {args.results}, data under "
             f"{args.data_dir}; code at git {sha} ({'uncommitted changes' if dirty else 'clean work tree'})"]
    todo, estimates = [], []
    for entry in PLAN:
        status: Status = statuses[entry.key]
        n_seeds = wanted[entry.key].get("n_seeds")
        if not status.todo:
            lines.append(f"keep  {entry.key} (n_seeds={n_seeds}): up to date, {status.record.folder}")
            continue
        todo.append(entry.key)
        estimate = estimate_seconds(wanted[entry.key], records.get(entry.key, []))
        estimates.append(estimate)
        lines.append(f"run   {entry.key} (n_seeds={n_seeds}): {status.reason}; "
                     f"estimated {estimate_text(estimate)}")
        if data_steps[entry.key] is not None:
            lines.append(f"        first: python {shlex.join(data_steps[entry.key])}")
        lines.append(f"        {_shown(commands[entry.key])}")
    pdf = "generated tables" if args.no_pdf else args.paper_dir / "report.pdf"
    if todo:
        lines.append(f"to run: {len(todo)} of {len(PLAN)} ({total_estimate(estimates)}); then the report: {pdf}")
    else:
        lines.append(f"nothing to run: all {len(PLAN)} runs are up to date; then the report: {pdf}")
    return lines, todo


def main(argv: list[str] | None = None) -> int:
    try:
        args = _parse(argv)
        stamp = dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        commands = {e.key: _command(e, args, stamp) for e in PLAN}
        wanted = _compose({e.key: e.run_overrides(args.quick, args.data_dir)
                           + [f"out_dir={args.results}", "progress=false"] for e in PLAN}, args.launcher)
    except UsageError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    sha, dirty = git_state(REPO)
    changes = ChangeCache(REPO)
    records = _records(args.results, {e.exp for e in PLAN})
    deps = {e.key: experiment_dependencies(REPO, e.exp, e.extra_scripts) for e in PLAN}
    statuses = {e.key: judge(e.key, wanted[e.key], records.get(e.key, []),
                             lambda r, k=e.key: code_reason(r, deps[k], changes.changed)) for e in PLAN}
    data_steps = {e.key: e.data.argv(args.data_dir) if e.data else None for e in PLAN}
    lines, todo = _plan_text(args, statuses, wanted, records, commands, data_steps, sha, dirty)
    lines += filter(None, (cached_data_note(REPO, e, statuses[e.key], changes.changed, args.data_dir) for e in PLAN))
    if args.dry_run:
        print("\n".join(lines))
        return 0
    print("\n".join([lines[0], *(line for line in lines if line.startswith("note: "))]))
    if dirty:
        print("note: the work tree has uncommitted changes; runs made now will count as stale next time "
              "(commit first)")
    chosen = {k: s.record.folder for k, s in statuses.items() if not s.todo}
    if todo:
        before = {r.folder for rs in records.values() for r in rs}

        def find_folder(entry: PlannedRun) -> Path | None:
            """The folder the run just made: new since the start, with the planned config."""
            new = [r for r in _records(args.results, {entry.exp}).get(entry.key, [])
                   if r.folder not in before and not config_differences(r.config, wanted[entry.key])]
            return new[-1].folder if new else None

        log_dir = args.results / "reproduce-logs" / stamp
        log_dir.mkdir(parents=True, exist_ok=True)
        runner = Runner(log_dir, len(todo))
        jobs = args.jobs or (len(todo) if args.launcher else 1)
        entries = [e for e in PLAN if e.key in todo]
        pool = ThreadPoolExecutor(max_workers=jobs)
        try:
            futures = [pool.submit(runner.run, i + 1, e, commands[e.key], data_steps[e.key], find_folder)
                       for i, e in enumerate(entries)]
            made = dict(f.result() for f in futures)
        except KeyboardInterrupt:
            runner.stop()
            pool.shutdown(wait=True, cancel_futures=True)
            print("interrupted: the runs finished so far are kept; the report was not built", file=sys.stderr)
            return 130
        pool.shutdown()
        failed = [k for k, folder in made.items() if folder is None]
        if failed:
            print(f"error: {len(failed)} of {len(todo)} runs failed ({', '.join(failed)}); see their logs in "
                  f"{log_dir}; the report was not built", file=sys.stderr)
            return 1
        chosen.update(made)
    report_argv = [str(chosen[e.key]) for e in PLAN] + ["--results", str(args.results),
                                                        "--paper-dir", str(args.paper_dir)]
    report_argv += ["--quick"] * args.quick + ["--no-pdf"] * args.no_pdf
    return report.main(report_argv)


def _interrupt(signum, frame) -> None:
    """SIGTERM (``kill``, a scheduler's cancel) ends the runs like Ctrl-C."""
    raise KeyboardInterrupt


if __name__ == "__main__":
    signal.signal(signal.SIGTERM, _interrupt)
    sys.exit(main())
