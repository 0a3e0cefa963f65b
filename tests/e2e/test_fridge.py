"""The fridge experiment (SPEC 8.5): a short generated sequence end to end, and bad inputs."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest

from stslam.errors import ConfigError, InputFileError
from stslam.experiments import fridge
from stslam.rgbd.sequence import FridgeSequence, SequenceConfig
from stslam.io.mcap_write import write_fridge_mcap
from stslam.experiments.runner import execute

from conftest import REPO

# 90 frames (3 s) at 160 × 120: the door opens and closes within the run, the robot moves ~1 m.
SHORT = SequenceConfig(n_frames=90, width=160, height=120)
SEED = 7


@pytest.fixture(scope="module")
def short_mcap(tmp_path_factory):
    path = tmp_path_factory.mktemp("fridge") / "short.mcap"
    write_fridge_mcap(path, FridgeSequence(SHORT, SEED))
    return path


@pytest.fixture(scope="module")
def smoke(short_mcap, tmp_path_factory):
    """One run of the experiment on the short sequence (landmarks: tracks of ≥ 20 frames).

    A-SLAM's common axis waits for 5 agreeing revolute tracks, not the full runs' 8: this 3 s,
    160 × 120 run holds only 7–12 tracks revolute (the 300-frame runs 21–32), and with 8 it would
    never convert a landmark — the test would then only see the gated EKF.
    """
    from conftest import compose_config

    out = tmp_path_factory.mktemp("results")
    cfg = compose_config("fridge", [f"mcap={short_mcap}", f"seed={SEED}", "landmarks.min_track_frames=20",
                                    "filters.a_slam.common_axis.min_tracks=5"], out_dir=out)
    folder = execute(cfg)
    return folder, pd.read_csv(folder / "metrics.csv")


def test_smoke_axis_and_ate_ordering(smoke):
    folder, metrics = smoke
    ate = metrics.set_index("method")["ate_m"]
    row = metrics.set_index("method").loc["a_slam"]
    # Hinge axis: on this seed 0.21° / 3.8 cm (A-SLAM poses) and 0.23° / 1.0 cm (true poses); over the
    # 10 seeds of the full experiment at most 0.71° / 0.8 cm. The bound is the SPEC 11 target, 5° and 5 cm.
    assert row["axis_angle_deg"] < 5.0 and row["axis_dist_m"] < 0.05
    assert row["axis_angle_deg_true_poses"] < 5.0 and row["axis_dist_m_true_poses"] < 0.05
    # The axis is fitted on the revolute tracks and needs two (axis.min_tracks). Here 2 end revolute (3 before
    # the onset test: it holds the door's points out while they move, and the door opens and closes in 3 s).
    assert row["n_revolute"] >= 2
    # ATE ordering (SPEC 11): A-SLAM no worse than EKF SLAM, with no tolerance: over the 10 seeds EKF SLAM
    # was 0.17–0.36 m (door points drag it) and A-SLAM 0.005–0.012 m; here 0.28 vs 0.0096 m.
    assert ate["a_slam"] <= ate["ekf_slam"]
    # Against the gated EKF: a_slam − ekf_slam_gated over the 10 seeds had mean −0.0016 m and standard
    # deviation 0.0017 m, so mean + 3 sd = 0.0035 m bounds a seed's difference (here −0.0023 m).
    assert ate["a_slam"] <= ate["ekf_slam_gated"] + 0.0035
    assert (folder / "trajectories" / f"a_slam_seed{SEED}.tum").is_file()
    assert (folder / "trajectories" / f"groundtruth_seed{SEED}.tum").is_file()
    for name in ("tracks_axis", "trajectories", "model_probabilities"):
        assert (folder / "figures" / f"{name}.png").is_file()


def test_smoke_metrics_columns(smoke):
    _, metrics = smoke
    assert list(metrics["method"]) == ["odometry", "ekf_slam", "dyn_slam", "ekf_slam_gated", "a_slam"]
    assert np.all(np.isfinite(metrics["ate_m"])) and np.all(metrics["ate_m"] > 0)


@pytest.mark.parametrize("override, match", [
    ("methods=[ekf_slam,oracle]", r"methods\[1\]"),
    ("frontend.fb_max_px=0", "frontend.fb_max_px"),
    ("landmarks.max_landmarks=0", "landmarks.max_landmarks"),
    ("filters.a_slam.classify_every=0", r"filters\.a_slam\.classify_every"),
    ("filters.a_slam.convert=[static]", r"filters\.a_slam\.convert"),
    ("sequence.width=8", "width"),
])
def test_bad_config_is_rejected_before_work(compose_exp, override, match):
    with pytest.raises(ConfigError, match=match):
        fridge.run(compose_exp("fridge", override, "data_dir=/nonexistent/never"))


def test_missing_file_is_an_input_error(compose_exp, tmp_path):
    with pytest.raises(InputFileError, match="no such file"):
        fridge.run(compose_exp("fridge", f"mcap={tmp_path / 'nope.mcap'}"))


def _cli(args, out_dir):
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, str(REPO / "experiments" / "run.py"), "+exp=fridge", "progress=false",
                           f"out_dir={out_dir}", *args], cwd=REPO, env=env, capture_output=True, text=True,
                          timeout=300)


def test_truncated_and_topicless_files_end_with_one_line(short_mcap, tmp_path):
    truncated = tmp_path / "truncated.mcap"
    data = short_mcap.read_bytes()
    truncated.write_bytes(data[: len(data) // 2])
    topicless = tmp_path / "topicless.mcap"
    from mcap.writer import Writer
    with open(topicless, "wb") as handle:
        writer = Writer(handle)
        writer.start()
        writer.finish()
    for path, pattern in ((truncated, "truncated.mcap: "), (topicless, "topic /camera/rgb/image: missing")):
        done = _cli([f"mcap={path}"], tmp_path / "out")
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 2, done.stderr
        assert len(lines) == 1 and lines[0].startswith("error: ") and pattern in lines[0], done.stderr
        assert "Traceback" not in done.stderr
    assert not (tmp_path / "out" / "fridge").exists() or not any((tmp_path / "out" / "fridge").iterdir())


def test_odometry_controls_reproduce_the_odometry_path():
    from stslam.rgbd.sequence import integrate_controls
    from stslam.rgbd.slam_inputs import odometry_controls

    sequence = FridgeSequence(SequenceConfig(n_frames=40, width=32, height=24), 3)
    controls = odometry_controls(sequence.poses_odom_xytheta, sequence.times_s)
    poses = integrate_controls(sequence.poses_odom_xytheta[0], controls, 1.0 / 30.0)
    np.testing.assert_allclose(poses, sequence.poses_odom_xytheta, atol=1e-9)  # SPEC 5.1 inverted exactly
