"""Which folder keeps a run's seeds, and whether ``resume=true`` continues an earlier run (SPEC 12, 18).

A run keeps its finished seeds in a new ``.incomplete-…`` folder, made when its seeds start (after
the experiment has checked its configuration, so a rejected run leaves nothing). With
``resume=true`` it continues instead the newest incomplete run of the same experiment whose
resolved configuration and git commit are those of this run, apart from :data:`RESUME_IGNORED`
(how the seeds are run and shown, and where ``out_dir`` was written: the folder is found under
it). When incomplete runs exist but none has this configuration, a single run is refused with
the differing keys and nothing on disk changes; a job of a sweep (``-m``, where its siblings'
runs have other configurations by design) starts afresh, as does a run with nothing to continue.
Either says so on stdout.
"""

from __future__ import annotations

import os
import shlex
import shutil
import sys
from pathlib import Path

from stslam.config.readers import get_bool, lookup
from stslam.errors import ConfigError
from stslam.experiments.reproduce import config_differences
from stslam.experiments.seeds import SeedRunner, SeedWorkerDied, available_cores
from stslam.io.checkpoints import RunCheckpoints, RunLocked, incomplete_runs, run_meta
from stslam.io.results import git_state, incomplete_stem

RESUME_IGNORED = ("jobs", "progress", "resume", "out_dir")
SHOWN_DIFFERENCES = 6


def read_jobs(config: dict) -> int:
    """``jobs``: worker processes for the seeds, ≥ 1, or -1 for every core this process may use."""
    jobs = lookup(config, "jobs", 1)
    if isinstance(jobs, bool) or not isinstance(jobs, int) or not (jobs == -1 or jobs >= 1):
        raise ConfigError(f"jobs: expected an integer ≥ 1, or -1 for every core, got {jobs!r}")
    if jobs == -1:
        jobs = available_cores()
    if jobs > 1 and not hasattr(os, "fork"):
        raise ConfigError("jobs: parallel seeds need os.fork (Linux, macOS); use jobs=1 here")
    return jobs


def resume_command(argv: list[str] | None, exp: str) -> str:
    """The command that continues this run: the same one with ``resume=true``."""
    if argv:
        args = [a for a in argv[1:] if a.lstrip("+~").partition("=")[0] != "resume"]
        return shlex.join(["python", argv[0], *args, "resume=true"])
    return f"python experiments/run.py +exp={exp} <the same overrides> resume=true"


def _create(parent: Path, meta: dict) -> RunCheckpoints:
    stem = incomplete_stem()
    for n in range(10_000):
        try:
            return RunCheckpoints.create(parent / (stem if n == 0 else f"{stem}-{n}"), meta)
        except FileExistsError:
            continue
    raise RuntimeError(f"no free incomplete folder name for {parent / stem}")


def seed_runner(config: dict, exp: str, out_dir: Path, argv: list[str] | None = None,
                in_sweep: bool = False) -> SeedRunner:
    """The seeds' runner of this run: a new incomplete folder, or the one ``resume=true`` continues.

    Raises ConfigError (nothing written) for a bad ``jobs`` or ``resume``, or a refused resume.
    """
    jobs = read_jobs(config)
    resume = get_bool(config, "resume", default=False)
    parent = Path(out_dir) / exp
    sha = git_state()[0]
    fresh = SeedRunner(jobs=jobs, seed0=int(config["seed"]), hint=resume_command(argv, exp),
                       make_checkpoints=lambda: _create(parent, run_meta(exp, config, sha)))
    if not resume:
        return fresh
    wanted = {**config, "git_sha": sha}
    candidates = [(folder, meta) for folder, meta in incomplete_runs(parent) if meta.get("exp") == exp]
    locked = []
    for folder, meta in candidates:
        if config_differences({**meta["config"], "git_sha": meta.get("git_sha")}, wanted, RESUME_IGNORED):
            continue
        try:
            store = RunCheckpoints.open(folder)
        except RunLocked:
            locked.append(folder)
            continue
        print(f"resume: continuing {folder} ({store.n_units()} finished unit(s) of work kept)")
        fresh.checkpoints, fresh.make_checkpoints = store, None
        return fresh
    if locked:
        raise ConfigError(f"resume: the incomplete run {locked[0]} of this config is being run by another "
                          "process; wait for it to end (or stop it) and resume again")
    if candidates and not in_sweep:
        folder, meta = candidates[0]
        raise ConfigError(f"resume: no incomplete {exp} run under {parent} has this config; the newest, "
                          f"{folder.name}, differs in {_differences(meta, wanted)}. Nothing was changed: repeat "
                          "its command with resume=true, or run without resume=true to start afresh")
    others = f" ({len(candidates)} of other configs left as they are)" if candidates else ""
    print(f"resume: no incomplete {exp} run of this config under {parent}{others}; running from scratch")
    return fresh


def _differences(meta: dict, wanted: dict) -> str:
    """Every differing key, the shallowest first (an override's own key before the values it brought),
    the first :data:`SHOWN_DIFFERENCES` with their two values."""
    diffs = config_differences({**meta["config"], "git_sha": meta.get("git_sha")}, wanted, RESUME_IGNORED)
    diffs.sort(key=lambda line: line.partition(":")[0].count("."))  # stable: alphabetical within a depth
    shown = "; ".join(_short(line) for line in diffs[:SHOWN_DIFFERENCES])
    rest = [line.partition(":")[0] for line in diffs[SHOWN_DIFFERENCES:]]
    return shown + (f"; and {', '.join(rest)}" if rest else "")


def _short(line: str, width: int = 40) -> str:
    """``key: old → new`` with each value cut to ``width`` characters (a world's landmark list is long)."""
    key, _, values = line.partition(": ")
    old, _, new = values.rpartition(" → ")
    cut = [v if len(v) <= width else v[:width - 1] + "…" for v in (old, new)]
    return f"{key}: {cut[0]} → {cut[1]}"


def abandon(seeds: SeedRunner, error: BaseException) -> None:
    """After a failed or interrupted run: keep its finished seeds and say how to continue, or leave
    no folder when none finished."""
    store = seeds.checkpoints
    if store is None:
        return
    if store.n_units() == 0:
        store.close()
        shutil.rmtree(store.folder, ignore_errors=True)
        return
    store.close()
    if not isinstance(error, SeedWorkerDied):  # its message says it already
        print(f"\n{seeds.kept_line()}", file=sys.stderr)
