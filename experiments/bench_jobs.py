"""Wall time of a run's seeds with jobs=1 and jobs=n, side by side (issue 42, SPEC 18).

    python experiments/bench_jobs.py --jobs 2 --repeat 3 +exp=dynamic_slam world=kitchen n_seeds=8

Runs ``experiments/run.py <overrides> jobs=<j>`` for j = 1 and n, alternating, ``--repeat`` times
each, under ``--out`` (default a temporary folder, removed). Prints per run the wall time, the CPU
time of the run and its workers, the load average at the start (the machine may be shared), and
the largest resident memory of one worker (as the run reports it); then the median ratio of the
wall times and whether every run's ``metrics.csv`` is identical to the first jobs=1 run's (all
columns but any ending in ``_s``, wall times). Exit code 1 when a metrics file differs.
"""

from __future__ import annotations

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

REPO = Path(__file__).resolve().parent.parent


def _one(overrides: list[str], jobs: int, out: Path) -> dict:
    """Run once; wall and CPU seconds, load, memory, the results folder."""
    load = os.getloadavg()[0]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run([sys.executable, str(REPO / "experiments" / "run.py"), *overrides, f"jobs={jobs}",
                           "progress=false", f"out_dir={out}"], cwd=REPO, capture_output=True, text=True,
                          env=dict(os.environ, MPLBACKEND="Agg"))
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    load_end = os.getloadavg()[0]
    if done.returncode != 0:
        sys.exit(f"run failed (jobs={jobs}):\n{done.stderr[-3000:]}")
    folder = Path(re.findall(r"^results: (.*)$", done.stdout, re.M)[-1])
    worker = re.findall(r"each at most (\d+) MiB resident", done.stdout)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    return {"jobs": jobs, "wall_s": wall, "cpu_s": cpu,
            "load": load, "load_end": load_end, "worker_mib": int(worker[0]) if worker else None, "folder": folder}


def _metrics(folder: Path) -> pd.DataFrame:
    table = pd.read_csv(folder / "metrics.csv")
    return table[[c for c in table.columns if not c.endswith("_s")]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=2, help="jobs of the parallel runs (default 2)")
    parser.add_argument("--repeat", type=int, default=2, help="runs of each kind (default 2)")
    parser.add_argument("--out", type=Path, default=None, help="results root (default: a temporary folder)")
    parser.add_argument("overrides", nargs="+", help="the run's overrides, e.g. +exp=dynamic_slam world=kitchen")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench_jobs-") as tmp:
        out = args.out or Path(tmp)
        runs = []
        for _ in range(args.repeat):
            for jobs in (1, args.jobs):
                runs.append(_one(args.overrides, jobs, out))
                r = runs[-1]
                print(f"jobs={r['jobs']}: wall {r['wall_s']:6.1f} s, CPU {r['cpu_s']:6.1f} s, load at start/end "
                      f"{r['load']:.2f}/{r['load_end']:.2f}"
                      + (f", worker ≤ {r['worker_mib']} MiB" if r["worker_mib"] else ""), flush=True)
        peak_main = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        reference = _metrics(next(r["folder"] for r in runs if r["jobs"] == 1))
        same = all(_metrics(r["folder"]).equals(reference) for r in runs)
        serial = statistics.median(r["wall_s"] for r in runs if r["jobs"] == 1)
        parallel = statistics.median(r["wall_s"] for r in runs if r["jobs"] == args.jobs)
        print(f"median wall: jobs=1 {serial:.1f} s, jobs={args.jobs} {parallel:.1f} s, ratio {parallel / serial:.2f}; "
              f"largest process (a main one or a worker) {peak_main:.0f} MiB resident; "
              f"metrics.csv identical in every run: {same}")
    sys.exit(0 if same else 1)


if __name__ == "__main__":
    main()
