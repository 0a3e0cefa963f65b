"""Worlds and door scenarios read from ``world`` and ``door`` (stslam.config.sim)."""

from __future__ import annotations

import copy

import pytest

from stslam.config.sim import door_scenario_from_config, world_from_config
from stslam.errors import ConfigError

from conftest import compose_config


def test_bad_world_values_name_the_key():
    base = compose_config("dynamic_slam", [])
    world = dict(base["world"])
    bad = {**base, "world": {**world, "n_frames": 1}}
    with pytest.raises(ConfigError, match="world.n_frames: expected an integer ≥ 2"):
        world_from_config(bad)
    landmarks = [dict(lm) for lm in world["landmarks"]]
    landmarks[1]["radius"] = -0.5
    with pytest.raises(ConfigError, match=r"world.landmarks\[1\].radius: expected a number > 0.0"):
        world_from_config({**base, "world": {**world, "landmarks": landmarks}})
    landmarks = [dict(lm) for lm in world["landmarks"]]
    landmarks[0]["direction"] = [0.0, 0.0, 0.0]
    with pytest.raises(ConfigError, match=r"world.landmarks\[0\].direction: expected a non-zero direction"):
        world_from_config({**base, "world": {**world, "landmarks": landmarks}})
    landmarks = [dict(lm) for lm in world["landmarks"]]
    landmarks[0]["model"] = "helical"
    with pytest.raises(ConfigError, match=r"world.landmarks\[0\].model: expected one of static"):
        world_from_config({**base, "world": {**world, "landmarks": landmarks}})
    with pytest.raises(ConfigError, match=r"world.static_points\[1\]: expected a list of 3 numbers"):
        world_from_config({**base, "world": {**world, "static_points": [[0, 0, 0], [1, 2]]}})
    with pytest.raises(ConfigError, match="world.robot.type: expected one of circle, segments"):
        world_from_config({**base, "world": {**world, "robot": {"type": "spiral"}}})
    keyframed = [dict(lm) for lm in world["landmarks"]]
    keyframed[0]["motion"] = {"keyframes": [[5, 0.0], [3, 1.0]]}
    with pytest.raises(ConfigError, match=r"world.landmarks\[0\].motion.keyframes\[1\]: frames must increase"):
        world_from_config({**base, "world": {**world, "landmarks": keyframed}})


@pytest.fixture(scope="module")
def config():
    return compose_config("temporal_order")


@pytest.mark.parametrize("key, value, match", [
    ("spring_rest_angle", 0.9, r"door.spring_rest_angle: expected ≤ door.closed_angle = 0.6"),
    ("restitution", 1.5, r"door.restitution: expected a number ≥ 0 and ≤ 1, got 1.5"),
    ("natural_freq", 0.0, r"door.natural_freq: expected a number > 0, got 0.0"),
    ("push_accel", [0.5], r"door.push_accel: expected 2 numbers, got 1"),
    ("release_angle", [1.8, 0.5], r"door.release_angle\[1\]: expected > door.closed_angle = 0.6"),
    ("n_samples", 1, r"door.n_samples: expected an integer ≥ 2, got 1"),
    ("noise_sigma", "loud", r"door.noise_sigma: expected a number, got 'loud'"),
])
def test_scenario_rejects_bad_values(config, key, value, match):
    bad = copy.deepcopy(config)
    bad["door"][key] = value
    with pytest.raises(ConfigError, match=match):
        door_scenario_from_config(bad)
