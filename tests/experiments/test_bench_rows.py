"""The speed benchmark's bookkeeping (experiments/bench.py): which rows and ratios it writes, and the
A-SLAM without selection it times beside the filters. Nothing here is timed: the times are made up."""

from __future__ import annotations

import importlib.util

import numpy as np
import pandas as pd

from stslam.config.robot import sensor_from_config
from stslam.config.sim import world_from_config
from stslam.render.bench import benchmark_table
from stslam.sim.simulate import simulate
from stslam.slam.filters import make_filter, run_filter
from stslam.config.slam import filter_params_from_config

from conftest import REPO, compose_config


def _bench():
    spec = importlib.util.spec_from_file_location("stslam_bench_script", REPO / "experiments" / "bench.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _step_rows(bench, times: dict) -> list[dict]:
    return [{"seed": seed, "method": name, "step_time_s": t} for name, per_seed in times.items()
            for seed, t in enumerate(per_seed)]


def test_world_rows_give_both_ratios_per_seed():
    bench = _bench()
    times = {"ekf_slam": [1.0e-3, 2.0e-3], "a_slam": [8.0e-3, 12.0e-3], bench.NO_SELECTION: [1.5e-3, 2.6e-3]}
    rows, steps = bench.world_rows("kitchen", _step_rows(bench, times))
    frame = pd.DataFrame(rows)
    ratio = frame.dropna(subset=["step_time_ratio_kitchen"]).set_index("seed")["step_time_ratio_kitchen"]
    floor = frame.dropna(subset=["step_time_ratio_no_selection_kitchen"]).set_index("seed")[
        "step_time_ratio_no_selection_kitchen"]
    # 8/1 and 12/2; 1.5/1 and 2.6/2 (exact quotients of the made-up times, to round-off)
    np.testing.assert_allclose(ratio.loc[[0, 1]].to_numpy(), [8.0, 6.0], rtol=1e-12)
    np.testing.assert_allclose(floor.loc[[0, 1]].to_numpy(), [1.5, 1.3], rtol=1e-12)
    assert set(steps.columns) == set(times)
    # paper_square keeps the old metric names as well; other worlds do not write them
    assert "step_time_ratio" not in frame.columns
    paper, _ = bench.world_rows("paper_square", _step_rows(bench, times))
    assert {"step_time_s", "step_time_ratio"} <= set(pd.DataFrame(paper).columns)


def test_world_rows_without_the_no_selection_run_write_no_floor():
    bench = _bench()
    rows, _ = bench.world_rows("kitchen", _step_rows(bench, {"ekf_slam": [1e-3], "a_slam": [9e-3]}))
    assert "step_time_ratio_no_selection_kitchen" not in pd.DataFrame(rows).columns


def test_benchmark_table_lists_the_floor_ratio_under_the_ratio():
    steps = {"paper_square": pd.Series({"a_slam": 4e-3, "ekf_slam": 5e-4, "a_slam_no_selection": 8e-4})}
    lines = benchmark_table(steps, {"paper_square": 8.0}, pd.DataFrame({"method": []}), 5, 5,
                            {"paper_square": 1.6})
    ratio_at = next(i for i, line in enumerate(lines) if line.startswith("| **a_slam / ekf_slam**"))
    assert lines[ratio_at] == "| **a_slam / ekf_slam** (≤ 1.5) | **8.00** |"
    assert lines[ratio_at + 1] == "| a_slam_no_selection / ekf_slam | 1.60 |"
    assert "| a_slam_no_selection | 0.800 |" in lines
    plain = benchmark_table(steps, {"paper_square": 8.0}, pd.DataFrame({"method": []}), 5, 5)
    assert not any(line.startswith("| a_slam_no_selection / ekf_slam") for line in plain)


def test_no_selection_runner_is_a_slam_that_never_selects():
    # Fed only each landmark's first sighting, no selector reaches N_min: no decision is made, and
    # A-SLAM is then the gated EKF to the last bit (SPEC 6.3(a): before any decision every landmark is
    # a gated static point), so the benchmark's floor times the same arithmetic A-SLAM does around selection.
    bench = _bench()
    cfg = compose_config("dynamic_slam", ["world=paper_square"])
    world = world_from_config(cfg)
    run = simulate(world, sensor_from_config(cfg), np.random.default_rng(0))
    track = bench.no_selection_runner("world=paper_square")(run)
    gated = run_filter(make_filter("ekf_slam_gated", filter_params_from_config(cfg, "ekf_slam_gated"), world), run)
    assert all(report.decisions == () for report in track.landmarks.values())
    assert all(np.isnan(report.mu).all() for report in track.landmarks.values())
    np.testing.assert_array_equal(track.poses_xytheta, gated.poses_xytheta)
    np.testing.assert_array_equal(track.pose_covs, gated.pose_covs)


def test_comparison_table_puts_two_runs_side_by_side_with_their_ratio():
    from stslam.render.bench import comparison_table

    ours = pd.DataFrame([{"method": "selection", "selection_obs_per_s": 30000.0},
                         {"method": "all_filters", "seed_time_s": 0.2}, {"method": "all_filters", "seed_time_s": 0.4},
                         {"method": "a_slam", "step_time_s_kitchen": 2e-3}])
    base = pd.DataFrame([{"method": "selection", "selection_obs_per_s": 10000.0},
                         {"method": "all_filters", "seed_time_s": 0.5}, {"method": "a_slam", "step_time_s_kitchen": 4e-3}])
    lines = comparison_table(ours, base, "new", "old")
    assert lines[0] == "| measure | new | old | ratio | target |"
    rows = {line.split(" | ")[0].lstrip("| "): line.split(" | ")[1:] for line in lines[2:]}
    assert rows["online selection (observations/s)"] == ["30,000", "10,000", "3.00", "≥ 2 |"]
    assert rows["one `dynamic_slam` seed, all five filters (s)"][:3] == ["0.30", "0.50", "0.60"]  # median of ours
    assert rows["A-SLAM per step, kitchen (ms)"][:3] == ["2.000", "4.000", "0.50"]
    assert not any("pipeline" in line for line in lines)  # measured in neither run: left out


def test_compare_names_a_folder_without_metrics(tmp_path, capsys):
    import pytest

    with pytest.raises(SystemExit) as exit_info:
        _bench().main(["--compare", str(tmp_path), "--selection-only"])
    assert exit_info.value.code != 0
    err = capsys.readouterr().err
    assert "--compare" in err and str(tmp_path) in err and "metrics.csv" in err


def test_benchmark_table_gives_each_seed_time_its_own_row_and_target():
    """The three whole-seed times share the metric seed_time_s and are told apart by their method."""
    steps = {"kitchen": pd.Series({"a_slam": 4e-3, "ekf_slam": 5e-4})}
    metrics = pd.DataFrame({"method": ["all_filters", "all_filters@isam2", "all_filters@kitchen@isam2"],
                            "seed_time_s": [0.5, 3.25, 49.0]})
    lines = benchmark_table(steps, {"kitchen": 8.0}, metrics, 1, 1)
    assert "| one `dynamic_slam` seed, all five filters (s) | 0.50 | < 1 |" in lines
    assert "| the same under `backend=isam2` (s) | 3.25 | ≤ 10 |" in lines
    assert "| one kitchen seed under `backend=isam2`, all five (s) | 49.00 | ≤ 30 |" in lines


def test_selection_free_seed_time_swaps_a_slams_best_run_for_the_no_selection_one():
    bench = _bench()
    steps = pd.DataFrame({"a_slam": [2e-3, 3e-3], bench.NO_SELECTION: [0.5e-3, 1e-3], "ekf_slam": [1e-4, 1e-4]})
    rows = bench.selection_free_rows([0.5, 0.6], steps, 100)
    # 0.5 − (2 − 0.5) ms × 100 frames = 0.35 s; 0.6 − (3 − 1) ms × 100 = 0.4 s (made-up times, to round-off)
    assert [r["method"] for r in rows] == ["all_filters_no_selection"] * 2
    np.testing.assert_allclose([r["seed_time_s"] for r in rows], [0.35, 0.4], rtol=1e-12)
    assert bench.selection_free_rows([0.5], steps.drop(columns=[bench.NO_SELECTION]), 100) == []


def test_comparison_sets_the_selection_free_seed_beside_the_baselines_whole_seed():
    from stslam.render.bench import SELECTION_FREE, comparison_table

    ours = pd.DataFrame([{"method": "all_filters", "seed_time_s": 0.4},
                         {"method": "all_filters_no_selection", "seed_time_s": 0.3}])
    base = pd.DataFrame([{"method": "all_filters", "seed_time_s": 0.5}])
    rows = {line.split(" | ")[0].lstrip("| "): line.split(" | ")[1:] for line in comparison_table(ours, base, "a", "b")[2:]}
    assert rows[SELECTION_FREE][:3] == ["0.30", "0.50", "0.60"]
    # a baseline run alone has no selection-free row to compare (its seed is compared once, above)
    assert not any(SELECTION_FREE in line for line in comparison_table(base, base, "a", "b"))


def test_benchmark_table_gives_the_peak_memory_of_the_kernels_first_calls_apart():
    """A fresh checkout's compilation (in a child process) sets the first, not the benchmark's own peak."""
    steps = {"kitchen": pd.Series({"a_slam": 4e-3, "ekf_slam": 5e-4})}
    metrics = pd.DataFrame([{"method": "kernels", "kernel_warmup_s": 30.4, "kernel_warmup_peak_rss_mb": 790.0},
                            {"method": "process", "peak_rss_mb": 537.0}])
    lines = benchmark_table(steps, {"kitchen": 8.0}, metrics, 1, 1)
    assert "| peak memory of the process that made those calls (MB) | 790 |  |" in lines
    assert "| peak memory (MB) | 537 |  |" in lines
