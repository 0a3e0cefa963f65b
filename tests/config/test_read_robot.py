"""The sensor read from ``sensor`` (stslam.config.robot)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.config.robot import sensor_from_config
from stslam.errors import ConfigError


def test_sensor_config_is_checked():
    good = {"sensor": {"fov": "cone", "sigma": 0.04, "half_angle_deg": 45.0, "max_range_m": 4.0}}
    sensor = sensor_from_config(good)
    np.testing.assert_allclose(sensor.R, 0.0016 * np.eye(3))
    with pytest.raises(ConfigError, match="sensor.sigma: expected a number > 0.0"):
        sensor_from_config({"sensor": {**good["sensor"], "sigma": 0.0}})
    with pytest.raises(ConfigError, match="sensor.fov: expected one of cone, pinhole"):
        sensor_from_config({"sensor": {**good["sensor"], "fov": "fisheye"}})
