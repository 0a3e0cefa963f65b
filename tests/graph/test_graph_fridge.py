"""The fridge experiment under backend=isam2 (SPEC 14) on a short generated sequence."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.experiments import fridge
from stslam.io.mcap_write import write_fridge_mcap
from stslam.rgbd.sequence import FridgeSequence, SequenceConfig

pytest.importorskip("gtsam")


def test_fridge_runs_under_isam2_with_smoothed_and_causal_scores(tmp_path):
    from conftest import compose_config

    path = tmp_path / "short.mcap"
    write_fridge_mcap(path, FridgeSequence(SequenceConfig(n_frames=90, width=160, height=120), 7))
    cfg = compose_config("fridge", [f"mcap={path}", "seed=7", "landmarks.min_track_frames=20",
                                    "filters.a_slam.common_axis.min_tracks=5", "backend=isam2",
                                    "methods=[ekf_slam_gated,a_slam]", "scene.seeds=[]"], out_dir=tmp_path / "out")
    metrics = fridge.run(cfg).metrics.set_index("method")
    for name in ("ekf_slam_gated", "a_slam"):
        row = metrics.loc[name]
        assert np.isfinite([row["ate_m"], row["ate_online_m"], row["nees"], row["nees_online"]]).all()
    assert np.isnan(metrics.loc["odometry", "ate_online_m"])  # dead reckoning has no causal/smoothed pair
