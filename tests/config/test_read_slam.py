"""A-SLAM's settings read from ``filters.a_slam`` (stslam.config.slam)."""

from __future__ import annotations

import pytest

from stslam.config.slam import a_slam_from_config
from stslam.errors import ConfigError

from conftest import compose_config


def test_a_slam_settings_defaults_leave_dynamic_slam_as_it_was():
    params = a_slam_from_config(compose_config("dynamic_slam", []))
    assert params.convert == ("prismatic", "revolute")
    assert params.classify_every == 1 and params.common_axis is None


@pytest.mark.parametrize("override, match", [
    ("+filters.a_slam.convert=[static]", r"filters\.a_slam\.convert"),
    ("+filters.a_slam.convert=[revolute,revolute]", r"filters\.a_slam\.convert"),
    ("+filters.a_slam.classify_every=0", r"filters\.a_slam\.classify_every"),
    ("+filters.a_slam.common_axis.bogus=1", r"filters\.a_slam\.common_axis: unknown option"),
    ("+filters.a_slam.common_axis.min_tracks=1", r"filters\.a_slam\.common_axis\.min_tracks"),
])
def test_a_slam_settings_reject_bad_values(override, match):
    with pytest.raises(ConfigError, match=match):
        a_slam_from_config(compose_config("dynamic_slam", [override]))
