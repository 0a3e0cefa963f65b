"""The iSAM2 back end's settings read from ``isam2.*`` (stslam.config.backend), with a world's own
``conf/isam2/<world>.yaml`` composed after ``conf/exp/dynamic_slam.yaml``."""

from __future__ import annotations

from dataclasses import replace

import pytest

from stslam.config.backend import backend_description, isam2_from_config
from stslam.config.slam import a_slam_from_config

from conftest import compose_config


def test_the_kitchens_baselines_run_over_a_lag_and_the_other_worlds_keep_the_whole_run():
    kitchen = isam2_from_config(compose_config("dynamic_slam", ["world=kitchen"]))
    assert kitchen.lag_s == 1.0 and kitchen.windowed == ("ekf_slam", "dyn_slam", "ekf_slam_gated")
    for world in ("square_centred", "paper_square", "kitchen_points"):  # no conf/isam2/<world>.yaml
        settings = isam2_from_config(compose_config("dynamic_slam", [f"world={world}"]))
        assert settings.lag_s is None and settings.windowed == ()
    # the command line still has the last word over the world's file
    override = isam2_from_config(compose_config("dynamic_slam", ["world=kitchen", "isam2.windowed=[]"]))
    assert override.windowed == () and override.lag_s == 1.0
    # the world's file changes nothing else of the experiment's iSAM2 settings
    square = isam2_from_config(compose_config("dynamic_slam", ["world=square_centred"]))
    assert replace(kitchen, lag_s=None, windowed=()) == square


def test_an_articulated_landmark_waits_five_static_verdicts_before_it_is_static_again():
    assert a_slam_from_config(compose_config("dynamic_slam", [])).static_hold == 5
    assert a_slam_from_config(compose_config("dynamic_slam", ["filters.a_slam.static_hold=1"])).static_hold == 1


def test_the_bodies_keep_their_sightings_with_the_static_points_pose_by_default():
    assert a_slam_from_config(compose_config("dynamic_slam", [])).bodies.evidence_pose == "static"
    posterior = ["+filters.a_slam.bodies.evidence_pose=posterior"]
    assert a_slam_from_config(compose_config("dynamic_slam", posterior)).bodies.evidence_pose == "posterior"


def test_a_runs_header_names_its_back_end_and_the_methods_over_the_lag():
    assert backend_description(compose_config("dynamic_slam", ["world=kitchen"])) == "back end: EKF"
    kitchen = backend_description(compose_config("dynamic_slam", ["world=kitchen", "backend=isam2"]))
    assert kitchen.startswith("back end: iSAM2 (ekf_slam, dyn_slam, ekf_slam_gated over a fixed lag of 1 s")
    # only the methods of the run are named
    gated = backend_description(compose_config("dynamic_slam", ["world=kitchen", "backend=isam2",
                                                                "methods=[a_slam,ekf_slam_gated]"]))
    assert gated.startswith("back end: iSAM2 (ekf_slam_gated over a fixed lag of 1 s")
    alone = compose_config("dynamic_slam", ["world=kitchen", "backend=isam2", "methods=[a_slam,oracle]"])
    assert backend_description(alone) == "back end: iSAM2 (every method over the whole run)"
    square = backend_description(compose_config("dynamic_slam", ["world=square_centred", "backend=isam2"]))
    assert square == "back end: iSAM2 (every method over the whole run)"


def test_an_optional_value_is_none_when_absent_or_null_and_checked_otherwise():
    from stslam.config.readers import get_float, get_optional
    from stslam.errors import ConfigError

    assert get_optional(get_float, {}, "isam2.lag_s", low=0.0, low_open=True) is None
    assert get_optional(get_float, {"isam2": {"lag_s": None}}, "isam2.lag_s", low=0.0, low_open=True) is None
    assert get_optional(get_float, {"isam2": {"lag_s": 2}}, "isam2.lag_s", low=0.0, low_open=True) == 2.0
    with pytest.raises(ConfigError, match=r"isam2\.lag_s: expected a number > 0\.0, got 0\.0"):
        get_optional(get_float, {"isam2": {"lag_s": 0}}, "isam2.lag_s", low=0.0, low_open=True)
