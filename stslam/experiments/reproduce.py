"""The runs behind the reproduction report, and when an earlier run can stand in for one.

:data:`PLAN` lists every run ``paper/report.tex`` uses: its report key
(``<experiment>[-<variant>]``, as ``experiments/report.py`` groups runs), the
overrides of ``python experiments/run.py +exp=<experiment>`` that make it, the
overrides ``--quick`` adds (small seed counts; without them the configs'
defaults, the counts the report states) and any data it needs made first.

An earlier complete run stands in for a planned one when (:func:`judge`)

1. its resolved configuration equals the one the plan composes now, apart from
   :data:`IGNORED_KEYS` (where results and cached data go, progress bars): a
   quick run and a full run differ in their seed counts and never stand in for
   each other;
2. it was made from a clean work tree (``git_dirty`` false in ``version.json``);
   with uncommitted changes its code cannot be known;
3. git knows its commit, and none of the files the run depends on differs
   between that commit and the files on disk now. The dependencies are the run
   script, the runner, the experiment's module, a data step's script and every
   package module they import (:mod:`stslam.experiments.code_deps`), so a change
   to one experiment's module makes only that experiment's runs stale, and a
   change to a shared module (``stslam/slam/core.py``) those of every
   experiment importing it.

Otherwise the run is redone. The rule does not see package versions
(``version.json`` records them) or data files cached from earlier runs (the
fridge sequences in ``data/``, kept by name).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from stslam.experiments.code_deps import experiment_dependencies, import_closure

# where results and cached sequences go, progress bars and how seeds are run: they do not change a run's numbers
IGNORED_KEYS = ("out_dir", "progress", "data_dir", "jobs", "resume")
DATA_PLACEHOLDER = "{data}"


@dataclass(frozen=True)
class DataStep:
    """A script run before the experiment to make its input files (``{data}``: the data folder)."""

    script: str
    args: tuple[str, ...]

    def argv(self, data_dir: str) -> list[str]:
        return [self.script, *(a.replace(DATA_PLACEHOLDER, data_dir) for a in self.args)]


@dataclass(frozen=True)
class CachedData:
    """Files an experiment makes once and then reuses (``files``: a glob, ``{data}`` the data folder),
    and the module that makes them: when its code changed, the files may be out of date."""

    module: str
    files: str


@dataclass(frozen=True)
class PlannedRun:
    """One run the report uses: ``+exp=<exp>`` with ``overrides`` (and ``quick`` for ``--quick``)."""

    key: str
    exp: str
    overrides: tuple[str, ...] = ()
    quick: tuple[str, ...] = ()
    data: DataStep | None = None
    cached: CachedData | None = None

    def run_overrides(self, quick: bool, data_dir: str) -> list[str]:
        """``+exp=…`` and the overrides (a quick one replacing one of the same key), ``{data}`` → ``data_dir``."""
        items = {item.partition("=")[0]: item for item in (f"+exp={self.exp}", *self.overrides)}
        items.update({item.partition("=")[0]: item for item in (self.quick if quick else ())})
        return [item.replace(DATA_PLACEHOLDER, data_dir) for item in items.values()]

    @property
    def extra_scripts(self) -> tuple[str, ...]:
        return (self.data.script,) if self.data else ()


_SLAM_QUICK = ("n_seeds=2",)
PLAN = (
    PlannedRun("structure_fit", "structure_fit", quick=("n_seeds=20", "sweep.n_seeds=3")),
    PlannedRun("temporal_order", "temporal_order", quick=("n_seeds=3",)),
    PlannedRun("articulation_estimation", "articulation_estimation", quick=("n_seeds=3",)),
    PlannedRun("dynamic_slam-square_centred", "dynamic_slam", quick=_SLAM_QUICK),
    PlannedRun("dynamic_slam-square_centred-order1", "dynamic_slam", ("motion_noise_order=1",), _SLAM_QUICK),
    PlannedRun("dynamic_slam-square_centred-sigma0.2", "dynamic_slam", ("sensor.sigma=0.2",), _SLAM_QUICK),
    PlannedRun("dynamic_slam-paper_square", "dynamic_slam", ("world=paper_square",), _SLAM_QUICK),
    PlannedRun("dynamic_slam-paper_square-pinhole-noisefree_controls", "dynamic_slam",
               ("world=paper_square", "sensor=pinhole", "robot.control_noise=false"), _SLAM_QUICK),
    # The kitchen with A-SLAM told the truth of its onsets beside it (the bound of docs/decisions.md, 2026-12-06).
    PlannedRun("dynamic_slam-kitchen", "dynamic_slam",
               ("world=kitchen", "methods=[ekf_slam,dyn_slam,ekf_slam_gated,a_slam,a_slam_truth_onsets,oracle]"),
               _SLAM_QUICK),
    PlannedRun("dynamic_slam-kitchen-iter3", "dynamic_slam", ("world=kitchen", "update_iterations=3"), _SLAM_QUICK),
    PlannedRun("fridge", "fridge", ("data_dir={data}",), ("n_seeds=1",),
               cached=CachedData("stslam/experiments/datasets.py", "{data}/fridge_*.mcap")),
    PlannedRun("dynamic_slam-square_centred-isam2", "dynamic_slam", ("backend=isam2",), _SLAM_QUICK),
    # The kitchen under iSAM2: the three methods its comparison needs (A-SLAM, the gated baseline, the
    # oracle), ~1.5 min per seed of them on one core (seeds 0-4: 53, 21-26 and 8-10 s CPU); the plain EKF SLAM and
    # Dyn. SLAM are left out. Structures as graph variables (the default): held fixed as fitted, the
    # structure counts as exact and A-SLAM's marginals are overconfident (seed 0 NEES 16.4, 7.0 with them).
    PlannedRun("dynamic_slam-kitchen-isam2", "dynamic_slam",
               ("world=kitchen", "backend=isam2", "n_seeds=20", "methods=[ekf_slam_gated,a_slam,oracle]"),
               _SLAM_QUICK),
    PlannedRun("dynamic_slam-paper_square-pinhole-noisefree_controls-isam2", "dynamic_slam",
               ("world=paper_square", "sensor=pinhole", "robot.control_noise=false", "backend=isam2", "n_seeds=20"),
               _SLAM_QUICK),
    # ~1-2 min per fridge seed under iSAM2 on one core (observations at every third frame): the EKF run's ten sequences.
    PlannedRun("fridge-isam2", "fridge", ("data_dir={data}", "backend=isam2", "n_seeds=10"), ("n_seeds=1",),
               cached=CachedData("stslam/experiments/datasets.py", "{data}/fridge_*.mcap")),
    # the tracks are made first; --quick classifies the first ten of them
    PlannedRun("classify_tracks", "classify_tracks", ("tracks.glob={data}/tracks/*.txt",),
               ("tracks.glob={data}/tracks/track_00*.txt",),
               DataStep("experiments/make_tracks.py", ("out={data}/tracks", "n=100", "seed=0"))),
)


def planned(key: str) -> PlannedRun | None:
    """The plan's entry for report key ``key``, None for a key the report does not use."""
    return next((run for run in PLAN if run.key == key), None)


@dataclass(frozen=True)
class RunRecord:
    """What a complete results folder says about itself (``config.yaml``, ``version.json``)."""

    folder: Path
    config: dict
    version: dict = field(default_factory=dict)

    @property
    def sha(self) -> str:
        return str(self.version.get("git_sha", ""))

    @property
    def dirty(self) -> bool:
        return bool(self.version.get("git_dirty", True))  # unrecorded: the code cannot be known

    @property
    def duration_s(self) -> float | None:
        value = self.version.get("duration_s")
        return float(value) if isinstance(value, (int, float)) and math.isfinite(value) else None

    @property
    def n_seeds(self) -> int | None:
        value = self.config.get("n_seeds")
        return value if isinstance(value, int) and value > 0 else None


def _flatten(config: Mapping, prefix: str = "") -> dict:
    flat = {}
    for key, value in config.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping) and value:
            flat.update(_flatten(value, name + "."))
        else:
            flat[name] = value
    return flat


def _differing(recorded: Mapping, wanted: Mapping, ignored: tuple[str, ...]) -> list[tuple[str, str, str]]:
    old, new = _flatten(recorded), _flatten(wanted)
    out = []
    for key in sorted(set(old) | set(new)):
        if key.split(".")[0] in ignored:
            continue
        if old.get(key, KeyError) != new.get(key, KeyError):
            shown = [repr(side[key]) if key in side else "(absent)" for side in (old, new)]
            out.append((key, *shown))
    return out


def config_differences(recorded: Mapping, wanted: Mapping, ignored: tuple[str, ...] = IGNORED_KEYS) -> list[str]:
    """``"<dotted key>: <recorded> → <wanted>"`` for every value that differs, keys in ``ignored`` aside."""
    return [f"{key}: {old} → {new}" for key, old, new in _differing(recorded, wanted, ignored)]


# files changed since a sha (None: unknown sha) for a list of dependency paths
ChangedFiles = Callable[[str, list[str]], "list[str] | None"]


def code_reason(record: RunRecord, dependencies: list[str], changed: ChangedFiles, shown: int = 3) -> str | None:
    """Why ``record``'s code is not the code on disk now (rule 2 and 3 above), None when it is."""
    if record.dirty:
        return f"made from a work tree with uncommitted changes (git {record.sha or '?'})"
    files = changed(record.sha, dependencies)
    if files is None:
        return f"git {record.sha or '?'} is not a commit of this repository"
    if not files:
        return None
    more = f" and {len(files) - shown} more" if len(files) > shown else ""
    noun = "file" if len(files) == 1 else "files"
    return f"{len(files)} {noun} it depends on changed since git {record.sha}: {', '.join(files[:shown])}{more}"


@dataclass(frozen=True)
class Status:
    """The verdict on one planned run: ``todo`` with its reason, or the earlier run that stands in."""

    key: str
    todo: bool
    reason: str
    record: RunRecord | None = None


def judge(key: str, wanted: Mapping, records: list[RunRecord],
          code_check: Callable[[RunRecord], str | None]) -> Status:
    """Whether planned run ``key`` (config ``wanted``) must run, given its earlier runs ``records`` (oldest first).

    The newest run with the wanted configuration whose code is current stands in. Otherwise the
    reason names what differs from the newest run with that configuration (its code), or from the
    newest run of the key (its configuration).
    """
    if not records:
        return Status(key, True, "missing: no complete run")
    same = [r for r in reversed(records) if not config_differences(r.config, wanted)]
    for record in same:
        if code_check(record) is None:
            return Status(key, False, "up to date", record)
    if same:
        return Status(key, True, f"stale: {code_check(same[0])} ({same[0].folder.name})", same[0])
    newest = records[-1]
    diffs = config_differences(newest.config, wanted)
    more = f"; and {len(diffs) - 3} more" if len(diffs) > 3 else ""
    return Status(key, True, f"stale: config differs from {newest.folder.name}: {'; '.join(diffs[:3])}{more}",
                  newest)


def estimate_seconds(wanted: Mapping, records: list[RunRecord]) -> float | None:
    """Expected duration from earlier runs of the key: the newest timed run with the wanted config,
    else the newest timed run differing only in seed counts (``*n_seeds``), scaled by ``n_seeds``;
    None when there is neither."""
    timed = [r for r in reversed(records) if r.duration_s is not None]
    for record in timed:
        if not config_differences(record.config, wanted):
            return record.duration_s
    n_wanted = wanted.get("n_seeds")
    for record in timed:
        only_seeds = all(key.split(".")[-1] == "n_seeds" for key, *_ in _differing(record.config, wanted, IGNORED_KEYS))
        if only_seeds and record.n_seeds and isinstance(n_wanted, int):
            return record.duration_s * n_wanted / record.n_seeds
    return None


def format_duration(seconds: float | None) -> str:
    """``< 1 s``, ``45 s``, ``3 min 20 s``, ``2 h 05 min``; ``unknown`` for None."""
    if seconds is None:
        return "unknown"
    if seconds < 0.5:
        return "< 1 s"
    s = int(round(seconds))
    if s < 60:
        return f"{s} s"
    if s < 3600:
        return f"{s // 60} min {s % 60:02d} s"
    return f"{s // 3600} h {s % 3600 // 60:02d} min"


def estimate_text(seconds: float | None) -> str:
    """An estimated duration: ``unknown``, ``< 1 s`` or ``≈ 3 min 20 s``."""
    text = format_duration(seconds)
    return text if seconds is None or text.startswith("<") else f"≈ {text}"


def total_estimate(estimates: list[float | None]) -> str:
    """The summed estimate of runs to make, and how many have none."""
    known = [e for e in estimates if e is not None]
    unknown = len(estimates) - len(known)
    if not known:
        return "duration unknown: no earlier timed run"
    text = f"estimated {estimate_text(sum(known))} from earlier runs' recorded times, start-up not included"
    return text + (f"; {unknown} run{'s' if unknown > 1 else ''} of unknown duration" if unknown else "")


def cached_data_note(root: Path, entry: PlannedRun, status: Status, changed: ChangedFiles,
                     data_dir: str) -> str | None:
    """A warning when ``entry`` is redone after a change to the code that made its cached files.

    The run reuses those files whatever code made them (the fridge keeps its sequences by size and
    seed), so the user is told which files to delete to have them made anew.
    """
    record = status.record
    if entry.cached is None or not status.todo or record is None or record.dirty:
        return None
    files = changed(record.sha, import_closure(root, [entry.cached.module]))
    if not files:
        return None
    pattern = entry.cached.files.replace(DATA_PLACEHOLDER, data_dir)
    return (f"note: {entry.key} reuses {pattern}, which the code changed since git {record.sha} makes "
            f"({', '.join(files[:3])}{' …' if len(files) > 3 else ''}); delete those files to make them anew")


@dataclass(frozen=True)
class CodeOrigin:
    """Where one run of the report came from, for the title page."""

    key: str
    sha: str
    at_head: bool
    reason: str | None  # None: the code it depends on is the code on disk now


def dependencies_for(root: Path, key: str, exp: str) -> list[str]:
    """The files report key ``key`` (experiment ``exp``) depends on: its plan entry's data script too."""
    entry = planned(key)
    return experiment_dependencies(root, exp, entry.extra_scripts if entry else ())


def code_origins(root: Path, runs: Mapping[str, tuple[str, dict]], head_sha: str | None,
                 changed: ChangedFiles) -> list[CodeOrigin]:
    """:class:`CodeOrigin` of each report key → (experiment, ``version.json``)."""
    out = []
    for key, (exp, version) in sorted(runs.items()):
        record = RunRecord(Path(key), {}, version)
        reason = code_reason(record, dependencies_for(root, key, exp), changed)
        at_head = bool(head_sha) and bool(record.sha) and head_sha.startswith(record.sha)
        out.append(CodeOrigin(key, record.sha, at_head, reason))
    return out
