"""What a perfect onset test would give A-SLAM (issue 38, SPEC 18): its ATE and NEES against the oracle's.

    python experiments/onset_bound.py --seeds 0-19 [--csv out.csv] [overrides ...]

For each seed of ``+exp=dynamic_slam`` (``world=kitchen`` unless an override says otherwise) it runs the
oracle, A-SLAM as configured, and A-SLAM told by the simulation's truth which of its observations were
taken while the point moved (``run_a_slam``'s ``moving``: every observation of a point it holds static,
taken while that point truly moves, is held out as the onset tests hold out their own; articulated
landmarks are used as always). The second A-SLAM is no estimator, only a bound: no test of a track can
know a motion before it shows, so whatever A-SLAM's onset tests gain, they gain at most what it gains.
Prints per seed and on average ATE / the oracle's ATE and the NEES ratio (the ratio of the means over
seeds, as issue 38 states its bars). Overrides are Hydra's (``filters.a_slam.structure_inflation=30``).
"""

from __future__ import annotations

import stslam  # noqa: F401  (first: single-threaded BLAS before numpy loads; see stslam/__init__)
import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd
from tqdm import tqdm

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench import slam_config  # noqa: E402  (the benchmark's Hydra composition of +exp=dynamic_slam)

from stslam.config.robot import sensor_from_config  # noqa: E402
from stslam.config.sim import world_from_config  # noqa: E402
from stslam.config.slam import (filter_params_from_config, motion_noise_order_from_config,  # noqa: E402
                                update_iterations_from_config)
from stslam.slam.a_slam import run_a_slam  # noqa: E402
from stslam.slam.decision_scores import truly_moving  # noqa: E402
from stslam.slam.evaluation import pose_nees, score_track  # noqa: E402
from stslam.slam.filters import make_filter, run_filter  # noqa: E402
from stslam.sim.simulate import simulate  # noqa: E402

METHODS = ("oracle", "a_slam", "a_slam_perfect_onsets")


def seed_range(text: str) -> range:
    """``"0-19"`` → range(0, 20); ``"7"`` → range(7, 8)."""
    first, _, last = text.partition("-")
    try:
        low, high = int(first), int(last or first)
    except ValueError:
        raise SystemExit(f"--seeds: expected N or N-M (integers), got {text!r}") from None
    if high < low or low < 0:
        raise SystemExit(f"--seeds: expected 0 <= N <= M, got {text!r}")
    return range(low, high + 1)


def bound_rows(overrides: list[str], seeds: range, progress: bool = True) -> pd.DataFrame:
    """One row per (seed, method) of :data:`METHODS`: ``ate_m`` and ``nees`` (EKF back end)."""
    cfg = slam_config("world=kitchen", *overrides)
    world, sensor = world_from_config(cfg), sensor_from_config(cfg)
    order, iterations = motion_noise_order_from_config(cfg), update_iterations_from_config(cfg)
    a_slam_params = filter_params_from_config(cfg, "a_slam")
    oracle = make_filter("oracle", filter_params_from_config(cfg, "oracle"), world, order, iterations)
    a_slam = make_filter("a_slam", a_slam_params, world, order, iterations)
    moving = truly_moving(world)
    rows = []
    for seed in tqdm(seeds, desc="seeds", disable=not progress):
        run = simulate(world, sensor, np.random.default_rng(seed), bool(cfg["robot"]["control_noise"]))
        tracks = {"oracle": run_filter(oracle, run), "a_slam": run_filter(a_slam, run),
                  "a_slam_perfect_onsets": run_a_slam(a_slam_params, run, None, order, iterations, moving)}
        for name in METHODS:
            track = tracks[name]
            scores = score_track(world, track, pose_nees(world.poses_xytheta, track.poses_xytheta, track.pose_covs))
            rows.append({"seed": seed, "method": name, "ate_m": scores["ate_m"], "nees": scores["nees"]})
    return pd.DataFrame(rows)


def summary(rows: pd.DataFrame) -> pd.DataFrame:
    """Per seed and for the mean: ATE and NEES of each A-SLAM over the oracle's."""
    wide = rows.pivot(index="seed", columns="method", values=["ate_m", "nees"])
    table = pd.DataFrame({f"{name} {kind}": wide[kind][name] / wide[kind]["oracle"]
                          for name in METHODS[1:] for kind in ("ate_m", "nees")})
    means = wide.mean()
    table.loc["mean"] = [means[kind][name] / means[kind]["oracle"] for name in METHODS[1:] for kind in ("ate_m", "nees")]
    return table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", default="0-19", help="N or N-M (default 0-19, issue 38's seeds)")
    parser.add_argument("--csv", type=Path, default=None, help="also write the rows here (a new file)")
    parser.add_argument("overrides", nargs="*", help="Hydra overrides of +exp=dynamic_slam")
    args = parser.parse_args()
    seeds = seed_range(args.seeds)
    if args.csv is not None and args.csv.exists():
        raise SystemExit(f"--csv: {args.csv} exists; give a new file (nothing is overwritten)")
    rows = bound_rows(args.overrides, seeds)
    print(summary(rows).to_string(float_format=lambda v: f"{v:.3f}"))
    if args.csv is not None:
        rows.to_csv(args.csv, index=False)
        print(f"rows: {args.csv}")


if __name__ == "__main__":
    main()
