"""Speed and scale benchmark (SPEC 11, 16). Not a test: it measures and reports.

    python experiments/bench.py                     # everything, results/bench/<stamp>-<sha>/
    python experiments/bench.py --seeds 3 --sizes 42 100 300 1000 --skip-frontend
    python experiments/bench.py --seeds 3 --repeats 3 --skip-isam2 --against 3c73d16   # SPEC 18's side by side

Measures, in one process: the per-step time of each SLAM filter on ``paper_square``,
``square_centred`` (the default world) and ``kitchen``, the filters of a world taking
turns on the same inputs (the fastest of ``--repeats`` runs counts), and the A-SLAM /
EKF SLAM ratio per seed; beside them A-SLAM with its selectors fed only each landmark's first
sighting (``a_slam_no_selection``: no selection ever starts, everything else of A-SLAM runs), whose
ratio to EKF SLAM is what A-SLAM would cost were its online model selection free; one ``dynamic_slam`` seed of every filter end to end on the
default world under each back end (``ekf``; ``isam2`` unless ``--skip-isam2``, SPEC 14), and the
former with A-SLAM's run swapped for ``a_slam_no_selection``'s (method ``all_filters_no_selection``), and one
kitchen seed of every filter under ``isam2`` (issue 40's 30 s a seed);
the per-step time against the number of landmarks in the state (log–log slope); the
fridge front end's frames per second on 640×480 with one OpenCV thread; the fridge
pipeline end to end at 640×480 (MCAP decode, front end, landmark choice and A-SLAM with
its selection, as ``+exp=fridge`` runs it); observations per second through the online
selector on 100 realistic marker tracks (``conf/selection/marker_tracks.yaml``); and the
peak resident memory.

Times are CPU seconds of this process (``time.process_time``; BLAS and OpenCV on one
thread), which the other work on a shared machine disturbs less than the wall clock;
``frontend_fps`` alone is wall clock per frame, as ``bench_frontend.py`` measures it.
``summary.csv`` uses the metrics ``step_time_s`` (paper_square), ``step_time_s_<world>``,
``step_time_ratio`` (paper_square), ``step_time_ratio_<world>``,
``step_time_ratio_no_selection_<world>``, ``seed_time_s``,
``scaling_slope``, ``frontend_fps``, ``pipeline_fps``, ``selection_obs_per_s``,
``kernel_warmup_s`` (the compiled kernels' first calls, before every other measure, in a child
process: their compilation in a fresh checkout, their loading from numba's cache after),
``kernel_warmup_peak_rss_mb`` (that child's peak memory) and ``peak_rss_mb`` (this process's peak,
:mod:`stslam.eval.memory`; it loads the kernels from the cache the child filled, so a fresh checkout's
compilation does not count in it); ``benchmark.md`` is the table of the README's benchmark section.
"""

from __future__ import annotations

import stslam  # noqa: F401  (first: single-threaded BLAS before numpy loads; see stslam/__init__)
import argparse
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path

import numpy as np
import pandas as pd
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from stslam.config.robot import sensor_from_config
from stslam.config.sim import world_from_config
from stslam.errors import ConfigError
from stslam.eval.memory import peak_rss_mb
from stslam.experiments.kernels import first_calls, kernel_warmup_s
from stslam.experiments.baseline import run_baseline, shared_arguments
from stslam.experiments.cli import main_guard
from stslam.experiments.dynamic_slam import method_runners
from stslam.experiments.runner import TRACKED_PACKAGES
from stslam.io.results import write_run
from stslam.output import ExperimentOutput
from stslam.render.bench import benchmark_table, comparison_table, scaling_figure, step_time_figure
from stslam.slam.evaluation import run_seed
from stslam.slam.scaling import loglog_slope, state_step_time

REPO = Path(__file__).resolve().parent.parent
CONF = REPO / "conf"
WORLDS = ("paper_square", "square_centred", "kitchen")
DEFAULT_WORLD = "square_centred"
# A-SLAM whose selectors take only a landmark's first sighting (filters.a_slam.classify_every at its
# largest): no selection starts, so no decision, conversion or refit; gating, consensus and grouping run.
NO_SELECTION = "a_slam_no_selection"
NEVER = 2**31 - 1


def compose_exp(*overrides: str) -> dict:
    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("config", overrides=list(overrides))
    return OmegaConf.to_container(cfg, resolve=True)


def slam_config(*overrides: str) -> dict:
    return compose_exp("+exp=dynamic_slam", *overrides)


def no_selection_runner(*overrides: str):
    """A-SLAM of ``slam_config(*overrides)`` with its selectors fed only each landmark's first sighting."""
    cfg = slam_config(*overrides, f"++filters.a_slam.classify_every={NEVER}")
    return method_runners(cfg, ["a_slam"], world_from_config(cfg))["a_slam"]


def time_filters(cfg: dict, seeds: range, repeats: int = 1, extra: dict | None = None
                 ) -> tuple[list[dict], list[float]]:
    """Rows (seed, method, step_time_s) per filter, and the CPU time of each whole seed (``run_seed``).

    Each filter's time on a seed is the fastest of ``repeats`` runs on the same inputs, the
    first inside ``run_seed`` (as ``timeit`` does: the minimum is the run least disturbed by
    the rest of the machine), the filters taking turns so that none is favoured by a warm cache.
    ``extra`` (name → runner of a SimulatedRun) are timed the same way on the same inputs, ``repeats``
    times each, outside the seed's time.
    """
    world = world_from_config(cfg)
    sensor = sensor_from_config(cfg)
    runners = method_runners(cfg, list(cfg["methods"]), world)
    extra = dict(extra or {})
    rows, seed_times = [], []
    for seed in seeds:
        best = dict.fromkeys([*runners, *extra], np.inf)

        def timed(name, runner, best=best):
            def run(*args, **kwargs):
                started = time.process_time()
                track = runner(*args, **kwargs)
                best[name] = min(best[name], time.process_time() - started)
                return track
            return run

        started = time.process_time()
        result = run_seed(world, sensor, bool(cfg["robot"]["control_noise"]),
                          {name: timed(name, runner) for name, runner in runners.items()}, seed)
        seed_times.append(time.process_time() - started)
        for name, runner in extra.items():
            timed(name, runner)(result.run)
        for _ in range(repeats - 1):
            for name, runner in {**runners, **extra}.items():
                timed(name, runner)(result.run)
        for name, seconds in best.items():
            rows.append({"seed": seed, "method": name, "step_time_s": seconds / world.n_frames})
    return rows, seed_times


def world_rows(world: str, step_rows: list[dict]) -> tuple[list[dict], pd.DataFrame]:
    """metrics rows ``step_time_s_<world>`` per filter and ``step_time_ratio_<world>`` (A-SLAM / EKF SLAM)
    per seed, and ``step_time_ratio_no_selection_<world>`` (:data:`NO_SELECTION` / EKF SLAM) when it was
    timed; paper_square's also keep the names ``step_time_s`` and ``step_time_ratio``. Also the
    per-step times as a table (seed × method)."""
    names = [f"step_time_s_{world}"] + (["step_time_s"] if world == "paper_square" else [])
    rows = [{"seed": r["seed"], "method": r["method"], **dict.fromkeys(names, r["step_time_s"])} for r in step_rows]
    steps = pd.DataFrame(step_rows).pivot(index="seed", columns="method", values="step_time_s")
    if {"a_slam", "ekf_slam"} <= set(steps.columns):
        ratio_names = [f"step_time_ratio_{world}"] + (["step_time_ratio"] if world == "paper_square" else [])
        for seed, ratio in (steps["a_slam"] / steps["ekf_slam"]).items():
            rows.append({"seed": seed, "method": "a_slam/ekf_slam", **dict.fromkeys(ratio_names, ratio)})
    if {NO_SELECTION, "ekf_slam"} <= set(steps.columns):
        for seed, ratio in (steps[NO_SELECTION] / steps["ekf_slam"]).items():
            rows.append({"seed": seed, "method": f"{NO_SELECTION}/ekf_slam",
                         f"step_time_ratio_no_selection_{world}": ratio})
    return rows, steps


def selection_free_rows(seed_times: list[float], steps: pd.DataFrame, n_frames: int) -> list[dict]:
    """Rows ``seed_time_s`` of method ``all_filters_no_selection``: each seed's time with A-SLAM's run replaced
    by :data:`NO_SELECTION`'s, t − (t_A-SLAM − t_no-selection) (best runs, ``steps`` per step × ``n_frames``).
    What one seed would cost were A-SLAM's online selection free; an upper estimate, since the seed's own
    A-SLAM run is at least its best. No rows without both runs."""
    if not {"a_slam", NO_SELECTION} <= set(steps.columns):
        return []
    selection_s = (steps["a_slam"] - steps[NO_SELECTION]) * n_frames
    return [{"seed": s, "method": "all_filters_no_selection", "seed_time_s": t - float(selection_s.loc[s])}
            for s, t in enumerate(seed_times)]


def frontend_fps(n_frames: int) -> float:
    """Frames per second of the fridge front end on a fresh 640×480 sequence (one OpenCV thread)."""
    import cv2
    from bench_frontend import frame_times  # sibling script in experiments/

    from stslam.rgbd.frontend import TrackerSettings
    from stslam.rgbd.sequence import FridgeSequence, SequenceConfig
    from stslam.io.mcap_write import write_fridge_mcap

    cv2.setNumThreads(1)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "bench.mcap"
        write_fridge_mcap(path, FridgeSequence(SequenceConfig(n_frames=n_frames, width=640, height=480), 0))
        times, _ = frame_times(path, TrackerSettings())
    return float(times.size / times.sum())


def pipeline_fps(seed: int = 0) -> tuple[float, dict]:
    """Frames per CPU second of the fridge pipeline at 640×480, one core, and the seconds of its parts.

    The ``+exp=fridge`` settings at full size: the generated sequence of ``seed`` (rendering
    not counted), then, timed, MCAP decode and front end (``collect_tracks``), the landmark
    tracks (``select_landmarks``, ``inputs_from_tracks``) and A-SLAM with its online selection.
    """
    import cv2

    from stslam.config.backend import backend_runner_from_config
    from stslam.config.rgbd import sequence_from_config, tracker_from_config
    from stslam.config.slam import filter_params_from_config, motion_noise_order_from_config, \
        update_iterations_from_config
    from stslam.io.mcap_write import write_fridge_mcap
    from stslam.rgbd.sequence import FridgeSequence
    from stslam.rgbd.slam_inputs import inputs_from_tracks, select_landmarks
    from stslam.rgbd.tracks import collect_tracks
    from stslam.slam.filters import make_filter

    cv2.setNumThreads(1)
    cfg = compose_exp("+exp=fridge", "sequence.width=640", "sequence.height=480")
    frontend = tracker_from_config(cfg, "frontend")
    spec = make_filter("a_slam", filter_params_from_config(cfg, "a_slam"), None, motion_noise_order_from_config(cfg),
                       update_iterations_from_config(cfg))
    run_filter = backend_runner_from_config(cfg)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "pipeline.mcap"
        write_fridge_mcap(path, FridgeSequence(sequence_from_config(cfg["sequence"]), seed),
                          depth_encoding=cfg["sequence"]["depth_encoding"])
        started = time.process_time()
        tracks = collect_tracks(path, frontend)
        decoded = time.process_time()
        ids = select_landmarks(tracks, cfg["landmarks"]["min_track_frames"], cfg["landmarks"]["max_landmarks"])
        inputs = inputs_from_tracks(tracks, ids, cfg["odometry_alpha"])
        run_filter(spec, inputs, None)
        done = time.process_time()
    return tracks.n_frames / (done - started), {"decode_frontend_s": decoded - started, "a_slam_s": done - decoded,
                                                "n_frames": tracks.n_frames}


def marker_track_settings():
    """The online selector's settings of ``classify_tracks`` (realistic marker tracks)."""
    from stslam.config.selection import selection_from_config

    cfg = compose_exp("+exp=classify_tracks", "tracks.glob=-")
    return selection_from_config(cfg, dt=1.0 / float(cfg["tracks"]["rate_hz"]))


def selection_obs_per_s(settings, n_tracks: int, repeats: int) -> float:
    """Observations per second through the online selector with ``settings`` (classify_tracks',
    :func:`marker_track_settings`) on generated realistic marker tracks (seeds 0 … n_tracks − 1), the fastest
    of ``repeats`` passes."""
    from stslam.selection.selector import select_track
    from stslam.sim.marker_camera import MarkerCamera
    from stslam.sim.track_generator import generate_tracks

    tracks = [t.points_world for t in generate_tracks(n_tracks, 0, camera=MarkerCamera())]
    n = sum(t.shape[0] for t in tracks)
    best = np.inf
    for _ in range(repeats):
        started = time.process_time()
        for points in tracks:
            select_track(points, settings)
        best = min(best, time.process_time() - started)
    return n / best


def _baseline_metrics(folder: Path) -> pd.DataFrame:
    """metrics.csv of another benchmark run (``--compare``), read before any timing starts."""
    path = folder / "metrics.csv"
    if not path.is_file():
        raise ConfigError(f"--compare: no metrics.csv in {folder} (expected a folder written by experiments/bench.py)")
    metrics = pd.read_csv(path)
    if "method" not in metrics:
        raise ConfigError(f"--compare: {path} has no 'method' column (not a benchmark's metrics.csv)")
    return metrics


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="seeds per timing (default 5)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[42, 100, 200, 400, 700, 1000],
                        help="landmark counts for the scaling fit")
    parser.add_argument("--repeats", type=int, default=5,
                        help="runs per filter and seed for the per-step times; the fastest counts (default 5)")
    parser.add_argument("--worlds", nargs="+", default=list(WORLDS), choices=WORLDS,
                        help="worlds for the per-step times (default all three)")
    parser.add_argument("--frontend-frames", type=int, default=90)
    parser.add_argument("--skip-frontend", action="store_true", help="leave out the front end and the pipeline")
    parser.add_argument("--selection-only", action="store_true", help="only the selector's observations per second")
    parser.add_argument("--skip-isam2", action="store_true", help="leave out the iSAM2 back end (needs gtsam)")
    parser.add_argument("--out-dir", type=Path, default=Path("results"), help="root of results")
    against = parser.add_mutually_exclusive_group()
    against.add_argument("--compare", type=Path, default=None,
                         help="another benchmark run's folder (its metrics.csv), e.g. an older commit's run just "
                              "before this one: its measures side by side with this run's, with their ratios")
    against.add_argument("--against", metavar="COMMIT", default=None,
                         help="run COMMIT's own benchmark first, with the same options, in a scratch git worktree "
                              "(SPEC 18: e.g. 3c73d16), and compare this run with it")
    return parser


@main_guard("no results folder was written", CONF)
def main(argv: list[str] | None = None) -> int:
    parser = _parser()
    args = parser.parse_args(argv)
    if args.selection_only and args.against is not None:
        parser.error("--selection-only writes no run to compare: leave out --against")
    if args.against is not None:  # its run first, so that no measure of this run waits on it
        args.compare = run_baseline(args.against, shared_arguments(args), REPO, args.out_dir)
    baseline = _baseline_metrics(args.compare) if args.compare is not None else None
    if args.selection_only and baseline is not None:
        parser.error("--selection-only writes no run to compare: leave out --compare")
    print("compiled kernels' first calls …", file=sys.stderr)
    # First in a child process, which compiles them in a fresh checkout and leaves them in numba's cache, so
    # LLVM's memory (~260 MB, kept after compiling) stays out of this process's peak; then here, from the cache.
    settings = marker_track_settings()
    with ProcessPoolExecutor(1, mp_context=get_context("spawn")) as child:
        warmup, warmup_peak = child.submit(first_calls, settings).result()
    kernel_warmup_s(settings)
    print(f"compiled kernels: {warmup:.2f} s at their first calls (compiling them once per checkout, "
          f"else loading them from the cache), in a process whose peak memory was {warmup_peak:.0f} MB")
    print("online selection on 100 realistic marker tracks …", file=sys.stderr)
    selection = selection_obs_per_s(settings, 100, max(1, min(args.repeats, 3)))
    print(f"selection: {selection:.0f} observations/s (target ≥ 10,000)")
    if args.selection_only:
        return 0
    rows = [{"seed": 0, "method": "selection", "selection_obs_per_s": selection},
            {"seed": 0, "method": "kernels", "kernel_warmup_s": warmup, "kernel_warmup_peak_rss_mb": warmup_peak}]
    steps, seed_times = {}, None
    for world in args.worlds:
        print(f"per-step time of each filter on {world} …", file=sys.stderr)
        cfg = slam_config(f"world={world}")
        extra = {NO_SELECTION: no_selection_runner(f"world={world}")} if "a_slam" in cfg["methods"] else {}
        step_rows, times = time_filters(cfg, range(args.seeds), args.repeats, extra)
        new_rows, steps[world] = world_rows(world, step_rows)
        rows += new_rows
        if world == DEFAULT_WORLD:  # one dynamic_slam seed of every filter, the default world, ekf back end
            seed_times = times
            rows += [{"seed": s, "method": "all_filters", "seed_time_s": t} for s, t in enumerate(times)]
            rows += selection_free_rows(times, steps[world], world_from_config(cfg).n_frames)

    isam2_steps = None
    if not args.skip_isam2:
        # The iSAM2 back end (SPEC 14) on the same seeds of the default world, every filter once.
        print("one dynamic_slam seed of every filter under backend=isam2 …", file=sys.stderr)
        isam2_rows, isam2_seed_times = time_filters(slam_config("backend=isam2"), range(args.seeds))
        rows += [{**row, "method": f"{row['method']}@square_centred@isam2"} for row in isam2_rows]
        rows += [{"seed": s, "method": "all_filters@isam2", "seed_time_s": t} for s, t in enumerate(isam2_seed_times)]
        isam2_steps = pd.DataFrame(isam2_rows).groupby("method")["step_time_s"].median()
        print("one kitchen seed of every filter under backend=isam2 …", file=sys.stderr)  # (SPEC 18: ≤ 30 s)
        _, kitchen_times = time_filters(slam_config("backend=isam2", "world=kitchen"), range(1))
        rows += [{"seed": 0, "method": "all_filters@kitchen@isam2", "seed_time_s": kitchen_times[0]}]

    print(f"per-step time against state size {args.sizes} …", file=sys.stderr)
    scaling = [state_step_time(n) for n in args.sizes]
    slope = loglog_slope(args.sizes, scaling)
    rows.append({"seed": 0, "method": "ekf_core", "scaling_slope": slope})
    scaling_table = pd.DataFrame({"n_landmarks": args.sizes, "step_time_s": scaling})

    pipeline = None
    if not args.skip_frontend:
        print("fridge front end, 640x480 …", file=sys.stderr)
        rows.append({"seed": 0, "method": "frontend", "frontend_fps": frontend_fps(args.frontend_frames)})
        print("fridge pipeline (decode, front end, selection, A-SLAM), 640x480 …", file=sys.stderr)
        fps, pipeline = pipeline_fps()
        rows.append({"seed": 0, "method": "fridge_pipeline", "pipeline_fps": fps})
    rows.append({"seed": 0, "method": "process", "peak_rss_mb": peak_rss_mb()})

    metrics = pd.DataFrame(rows)
    medians = {world: table.median() for world, table in steps.items()}
    ratios = {name: {world: float((table[name] / table["ekf_slam"]).median())
                     for world, table in steps.items() if {name, "ekf_slam"} <= set(table.columns)}
              for name in ("a_slam", NO_SELECTION)}
    table = benchmark_table(medians, ratios["a_slam"], metrics, args.seeds, args.repeats, ratios[NO_SELECTION])
    figures = {"scaling": scaling_figure(args.sizes, scaling, slope)}
    if "paper_square" in medians:
        figures["step_time"] = step_time_figure(medians["paper_square"].to_dict())
    output = ExperimentOutput(metrics=metrics, figures=figures, lines=table,
                              tables={"scaling": scaling_table,
                                      **{f"step_time_{w}": t.reset_index() for w, t in steps.items()}})
    options = {name: str(value) if isinstance(value, Path) else value for name, value in vars(args).items()}
    folder = write_run(args.out_dir, "bench", {"exp_name": "bench", **options},
                       output, argv=sys.argv, packages=TRACKED_PACKAGES)
    if baseline is not None:
        compared = comparison_table(metrics, baseline, f"this run ({folder.name})", args.compare.name)
        table += ["", f"Side by side with {args.compare} (medians; ratio = this run / that one):", "", *compared]
    (folder / "benchmark.md").write_text("\n".join(table) + "\n", encoding="utf-8")
    print("\n".join(table))
    if isam2_steps is not None and DEFAULT_WORLD in medians:
        for name, value in isam2_steps.items():
            print(f"square_centred step time {name:15s} ekf {1e3 * medians[DEFAULT_WORLD][name]:8.3f} ms, isam2 "
                  f"{1e3 * value:8.3f} ms (median of {args.seeds} seeds, one run each under isam2)")
        seed_isam2 = metrics.loc[metrics["method"] == "all_filters@isam2", "seed_time_s"]
        kitchen_isam2 = metrics.loc[metrics["method"] == "all_filters@kitchen@isam2", "seed_time_s"]
        print(f"one {DEFAULT_WORLD} seed, every filter, backend=isam2: {seed_isam2.median():.2f} s median, "
              f"{seed_isam2.max():.2f} s max (target ≤ 10 s); one kitchen seed: {kitchen_isam2.max():.1f} s "
              f"(target ≤ 30 s)")
    if seed_times is None:
        print(f"(no seed_time_s: {DEFAULT_WORLD} not among --worlds)")
    if pipeline is not None:
        print(f"fridge pipeline parts: decode + front end {pipeline['decode_frontend_s']:.2f} s, landmarks + "
              f"A-SLAM {pipeline['a_slam_s']:.2f} s for {pipeline['n_frames']} frames (CPU)")
    print(f"results: {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
