"""The front end, the fridge sequence and make_data's request read from their blocks (stslam.config.rgbd)."""

from __future__ import annotations

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import OmegaConf

from stslam.config.rgbd import data_request_from_config, sequence_from_config, topics_from_config, tracker_from_config
from stslam.io.mcap_topics import DEFAULT_TOPICS
from stslam.errors import ConfigError
from stslam.rgbd.frontend import TrackerSettings
from stslam.rgbd.sequence import SequenceConfig

from conftest import REPO


@pytest.mark.parametrize("key, value, match", [
    ("quality_level", 0.0, "frontend.quality_level"),
    ("target_tracks", 0, "frontend.target_tracks"),
    ("depth_max_m", 0.1, "frontend.depth_max_m"),
])
def test_bad_frontend_settings_are_rejected(key, value, match):
    cfg = {"frontend": {**{k: getattr(TrackerSettings(), k) for k in TrackerSettings.__dataclass_fields__},
                        key: value}}
    with pytest.raises(ConfigError, match=match):
        tracker_from_config(cfg)


def _data_cfg(**changes):
    cfg = {"n_frames": 5, "width": 64, "height": 48, "rate_hz": 30.0,
           "fridge": {"hfov_deg": 62.7, "camera_height_m": 1.0, "camera_yaw_deg": 90.0, "path_radius_m": 2.5,
                      "path_radius_swing_m": 0.2, "path_start_deg": 5.0, "path_end_deg": 70.0,
                      "door_open_deg": 90.0, "door_times": [0.15, 0.4, 0.6, 0.85],
                      "alpha": [0.1, 0.05, 0.05, 0.1], "depth_noise_coefficient": 1.5e-3, "depth_min_m": 0.3,
                      "depth_max_m": 4.0, "max_incidence_deg": 75.0, "rgb_noise_std": 2.0}}
    for key, value in changes.items():
        if key in cfg:
            cfg[key] = value
        else:
            cfg["fridge"][key] = value
    return cfg


def test_config_is_read_and_bad_values_are_named():
    assert sequence_from_config(_data_cfg()) == SequenceConfig(n_frames=5, width=64, height=48)
    with pytest.raises(ConfigError, match=r"^width: expected an integer ≥ 16"):
        sequence_from_config(_data_cfg(width=8))
    with pytest.raises(ConfigError, match=r"^rate_hz: expected a number > 0"):
        sequence_from_config(_data_cfg(rate_hz=0))
    with pytest.raises(ConfigError, match=r"^fridge.door_times: expected 4 increasing"):
        sequence_from_config(_data_cfg(door_times=[0.5, 0.4, 0.6, 0.8]))
    with pytest.raises(ConfigError, match=r"^fridge.alpha\[2\]: expected a number ≥ 0"):
        sequence_from_config(_data_cfg(alpha=[0.1, 0.1, -0.1, 0.1]))
    with pytest.raises(ConfigError, match=r"^fridge.depth_max_m: expected a number > 0.3"):
        sequence_from_config(_data_cfg(depth_max_m=0.2))


def test_make_data_without_a_data_set_is_refused():
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base="1.3"):
        cfg = OmegaConf.to_container(compose("make_data"), resolve=True)
    with pytest.raises(ConfigError, match=r"^data: no data set chosen; add \+data=<name> with one of fridge"):
        data_request_from_config(cfg)


def test_mcap_topics_default_renamed_and_bad():
    assert topics_from_config({}) == DEFAULT_TOPICS
    fridge = OmegaConf.to_container(OmegaConf.load(REPO / "conf" / "exp" / "fridge.yaml"))
    assert topics_from_config(fridge) == DEFAULT_TOPICS  # the config lists SPEC 9's names
    topics = topics_from_config({"mcap_topics": {"rgb": "/cam/color", "odometry": "/wheels"}})
    assert (topics.rgb, topics.odometry, topics.depth) == ("/cam/color", "/wheels", DEFAULT_TOPICS.depth)
    for block, match in (({"colour": "/c"}, r"mcap_topics\.colour: unknown; expected one of rgb, depth"),
                         ({"rgb": ""}, r"mcap_topics\.rgb: expected a topic name, got ''"),
                         ({"rgb": "/x", "depth": "/x"}, r"mcap_topics: topic /x is given for more than one of")):
        with pytest.raises(ConfigError, match=match):
            topics_from_config({"mcap_topics": block})
