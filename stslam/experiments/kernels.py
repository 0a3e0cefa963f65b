"""The compiled kernels' first calls (numba, ``cache=True``; SPEC 11's benchmark, ``experiments/bench.py``).

A kernel's first call in a process compiles it (in a fresh checkout, ~30 s for all of them here) or loads
it from numba's on-disk cache. :func:`kernel_warmup_s` makes every kernel's first call from Python, with
the argument types the library passes, so that nothing is compiled later inside a timed measure;
:func:`first_calls` does it and reports the process's peak memory, for a child process that fills the
cache (LLVM keeps ~260 MB after compiling, which would otherwise count in the benchmark's own peak).
"""

from __future__ import annotations

import time

import numpy as np

from stslam.articulation.evidence import principal_axes
from stslam.articulation.window_evidence import revolute_log_odds, turn_evidence
from stslam.eval.memory import peak_rss_mb
from stslam.selection.observation_covariance import WeightedMotionSums
from stslam.selection.selector import select_track
from stslam.selection.settings import SelectionSettings
from stslam.sim.marker_camera import MarkerCamera
from stslam.sim.track_generator import generate_tracks
from stslam.slam.bodies.decisions import co_moving
from stslam.slam.bodies.joint import rigidity_test
from stslam.slam.bodies.pair_kernels import common_frames, pair_link


def kernel_warmup_s(settings: SelectionSettings) -> float:
    """CPU seconds of every kernel's first call: one generated marker track through the online selector
    with ``settings`` (the fits, the price, the bank, the IMM step), a door window's revolute : prismatic
    evidence and principal axes, a body-link pair test (the compiled whole and the parts the bodies call on
    their own: common frames, co-motion, rigidity, the pair's turn) and the running motion test of points
    with their own covariances."""
    points = generate_tracks(1, 0, camera=MarkerCamera())[0].points_world
    phi = np.linspace(0.0, 1.2, 40)
    door = np.column_stack([0.5 * np.cos(phi), 0.5 * np.sin(phi), np.ones(40)])
    frames, covs = np.arange(40), np.broadcast_to(1e-4 * np.eye(3), (40, 3, 3)).copy()
    started = time.process_time()
    select_track(points, settings)
    revolute_log_odds(door, np.full(40, 1e-4))
    pair_link(frames, door, covs, frames, 0.5 * door, covs, 10, 5, 0.9, 5)
    principal_axes(door)
    common_frames(frames, frames)
    co_moving(door, 0.5 * door)
    rigidity_test(door, 0.5 * door, covs, covs)
    turn_evidence(door, door + 0.1, covs, covs)  # a pair that kept its offset: both of its tests run
    sums = WeightedMotionSums(0.0)
    for n in range(1, 6):  # point by point: the compiled path
        sums.extend(door[:n], np.ones(40), covs)
    sums.p_value()
    return time.process_time() - started


def first_calls(settings: SelectionSettings) -> tuple[float, float]:
    """:func:`kernel_warmup_s` and the peak memory (MB) of the process it ran in."""
    seconds = kernel_warmup_s(settings)
    return seconds, peak_rss_mb()
