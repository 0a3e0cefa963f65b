"""backend=isam2 from the configuration (SPEC 14): errors, and a dynamic_slam run scored like evo."""

from __future__ import annotations

import copy
import sys

import numpy as np
import pytest

from stslam.errors import ConfigError
from stslam.experiments import dynamic_slam


def test_unknown_backend_is_named(compose_exp):
    cfg = compose_exp("dynamic_slam", "n_seeds=1", "backend=graph")
    with pytest.raises(ConfigError, match=r"^backend: expected one of ekf, isam2; got 'graph'$"):
        dynamic_slam.run(cfg)


def test_isam2_without_gtsam_says_what_to_install(compose_exp, monkeypatch):
    monkeypatch.setitem(sys.modules, "gtsam", None)  # import gtsam now raises ImportError
    cfg = compose_exp("dynamic_slam", "n_seeds=1", "backend=isam2")
    with pytest.raises(ConfigError, match=r'^backend: isam2 needs gtsam .*pip install -e "\.\[gtsam\]"') as info:
        dynamic_slam.run(cfg)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("key, value", [("isam2.floor_sigma", "0"), ("isam2.factorization", "lu"), ("isam2.structure", "free"),
                                        ("isam2.regate_probability", "1.0"), ("isam2.regate_robust", "maybe"),
                                        ("isam2.reread_restarts", "maybe"),
                                        ("isam2.observe_every", "0"), ("isam2.observe_every", "2.5"),
                                        ("isam2.structure_sigma", "0"), ("isam2.relinearize_threshold_q", "0"),
                                        ("isam2.structure_sigma_final", "0")])
def test_bad_isam2_settings_are_named(compose_exp, key, value):
    pytest.importorskip("gtsam")
    cfg = compose_exp("dynamic_slam", "n_seeds=1", "backend=isam2", f"{key}={value}")
    with pytest.raises(ConfigError, match=f"^{key}: expected"):
        dynamic_slam.run(cfg)


def _evo_ate(gt, est):
    from evo.core import metrics as evo_metrics
    from evo.core.trajectory import PoseTrajectory3D

    def traj(tum):
        return PoseTrajectory3D(positions_xyz=tum[:, 1:4].copy(),
                                orientations_quat_wxyz=np.column_stack([tum[:, 7], tum[:, 4:7]]),
                                timestamps=tum[:, 0].copy())

    ref, est = traj(gt), copy.deepcopy(traj(est))
    est.align(ref, correct_scale=False)
    ape = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    return ape.get_statistic(evo_metrics.StatisticsType.rmse)


def test_every_method_runs_under_isam2_and_evo_agrees_with_the_smoothed_ate(compose_exp):
    pytest.importorskip("gtsam")
    pytest.importorskip("evo")
    cfg = compose_exp("dynamic_slam", "n_seeds=1", "backend=isam2")
    out = dynamic_slam.run(cfg)
    metrics = out.metrics
    assert list(metrics["method"]) == ["ekf_slam", "dyn_slam", "ekf_slam_gated", "a_slam", "oracle"]
    assert {"ate_online_m", "rpe_online_m", "nees_online", "qr_fallbacks"} <= set(metrics.columns)
    assert metrics[["ate_m", "ate_online_m", "nees", "nees_online"]].notna().all().all()
    gt = out.trajectories["groundtruth_seed0.tum"]
    for _, row in metrics.iterrows():
        assert _evo_ate(gt, out.trajectories[f"{row['method']}_seed0.tum"]) == pytest.approx(row["ate_m"], abs=1e-9)


def test_command_line_without_gtsam_stops_with_one_line(tmp_path):
    import subprocess

    from conftest import REPO

    script = ("import runpy, sys; sys.modules['gtsam'] = None; "
              f"sys.argv = ['run.py', '+exp=dynamic_slam', 'backend=isam2', 'n_seeds=1', 'out_dir={tmp_path}']; "
              f"runpy.run_path({str(REPO / 'experiments' / 'run.py')!r}, run_name='__main__')")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: backend: isam2 needs gtsam ≥ 4.3"), done.stderr
    assert 'pip install -e ".[gtsam]"' in lines[0]
    assert not any(tmp_path.iterdir())
