"""The robot's sensor from the ``sensor`` block (``conf/sensor/<option>.yaml``; SPEC 5.2, 5.3)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from stslam.config.readers import get_choice, get_float
from stslam.robot.sensor import ConeFov, PinholeFov, Sensor


def sensor_from_config(cfg: Mapping) -> Sensor:
    """:class:`~stslam.robot.sensor.Sensor` from ``sensor.*``, every value checked (ConfigError)."""
    sigma = get_float(cfg, "sensor.sigma", low=0.0, low_open=True)
    kind = get_choice(cfg, "sensor.fov", ("cone", "pinhole"))
    if kind == "cone":
        half = get_float(cfg, "sensor.half_angle_deg", low=0.0, high=180.0, low_open=True)
        fov = ConeFov(np.deg2rad(half), get_float(cfg, "sensor.max_range_m", low=0.0, low_open=True))
    else:
        min_depth = get_float(cfg, "sensor.min_depth_m", low=0.0)
        fov = PinholeFov(
            focal_px=get_float(cfg, "sensor.focal_px", low=0.0, low_open=True),
            width_px=get_float(cfg, "sensor.width_px", low=0.0, low_open=True),
            height_px=get_float(cfg, "sensor.height_px", low=0.0, low_open=True),
            min_depth_m=min_depth,
            max_depth_m=get_float(cfg, "sensor.max_depth_m", low=min_depth, low_open=True),
            camera_height_m=get_float(cfg, "sensor.camera_height_m"),
        )
    return Sensor(sigma, fov)
