"""Benchmark of the fridge front end (SPEC 11: ≥ 30 frames/s on 640 × 480 on one core).

    python experiments/bench_frontend.py [--mcap PATH] [--frames N] [--width W --height H]

Without --mcap it renders a fresh sequence of N frames (default 120, seed 0) into a
temporary file. Only the front end is timed (corner detection, LK forward and
backward, depth lookup, back-projection), frame by frame, with OpenCV limited
to one thread; decoding the MCAP is not counted. Not a test: timings depend on
the machine and its load.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from stslam.experiments.cli import main_guard
from stslam.io.mcap_read import read_rgbd_frames
from stslam.io.mcap_write import write_fridge_mcap
from stslam.rgbd.frontend import FeatureTracker, TrackerSettings
from stslam.rgbd.sequence import FridgeSequence, SequenceConfig


def frame_times(path, settings: TrackerSettings) -> tuple[np.ndarray, int]:
    """Seconds spent in FeatureTracker.step per frame, and the tracks started."""
    tracker = FeatureTracker(settings)
    times = []
    for frame in read_rgbd_frames(path):
        started = time.perf_counter()
        tracker.step(frame.rgb, frame.depth_m, frame.K)
        times.append(time.perf_counter() - started)
    return np.array(times), tracker.n_started


@main_guard("nothing was measured")
def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mcap", type=Path, default=None)
    parser.add_argument("--frames", type=int, default=120)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--target-tracks", type=int, default=TrackerSettings.target_tracks)
    args = parser.parse_args()
    cv2.setNumThreads(1)
    settings = TrackerSettings(target_tracks=args.target_tracks)
    with tempfile.TemporaryDirectory() as folder:
        path = args.mcap
        if path is None:
            path = Path(folder) / "bench.mcap"
            write_fridge_mcap(path, FridgeSequence(SequenceConfig(n_frames=args.frames, width=args.width,
                                                                  height=args.height), 0))
        times, started = frame_times(path, settings)
    print(f"{path.name}: {times.size} frames, {started} tracks started, target {settings.target_tracks}")
    print(f"front end: {times.size / times.sum():.1f} frames/s (mean), median frame {1e3 * np.median(times):.2f} ms, "
          f"95th percentile {1e3 * np.percentile(times, 95):.2f} ms, one OpenCV thread")


if __name__ == "__main__":
    main()
