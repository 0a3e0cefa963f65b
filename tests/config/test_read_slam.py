"""A-SLAM's settings read from ``filters.a_slam`` (stslam.config.slam)."""

from __future__ import annotations

import pytest
from scipy.stats import chi2

from stslam.config.slam import a_slam_from_config
from stslam.errors import ConfigError

from conftest import compose_config


def test_a_slam_settings_defaults_leave_dynamic_slam_as_it_was():
    params = a_slam_from_config(compose_config("dynamic_slam", []))
    assert params.convert == ("prismatic", "revolute")
    assert params.classify_every == 1 and params.common_axis is None
    assert params.onset_windows == ()  # the shift onset test is off
    on = a_slam_from_config(compose_config("dynamic_slam", ["filters.a_slam.onset_windows=[3,5,10]"]))
    assert on.onset_windows == (3, 5, 10)
    assert on.window_bound == pytest.approx(chi2.ppf(1.0 - 0.01 / 3, 3))  # 0.99 shared by the three lengths
    assert params.onset_frame_quantile == 0.5  # the frame's median NIS lifts the onset allowance
    fridge = a_slam_from_config(compose_config("fridge", []))
    assert (fridge.onset_allowance, fridge.onset_threshold, fridge.onset_frame_quantile) == (1.5, 6.0, 0.1)


@pytest.mark.parametrize("override, match", [
    ("+filters.a_slam.convert=[static]", r"filters\.a_slam\.convert"),
    ("+filters.a_slam.convert=[revolute,revolute]", r"filters\.a_slam\.convert"),
    ("+filters.a_slam.classify_every=0", r"filters\.a_slam\.classify_every"),
    ("+filters.a_slam.common_axis.bogus=1", r"filters\.a_slam\.common_axis: unknown option"),
    ("+filters.a_slam.common_axis.min_tracks=1", r"filters\.a_slam\.common_axis\.min_tracks"),
    ("filters.a_slam.onset_windows=[5,0]", r"filters\.a_slam\.onset_windows"),
    ("filters.a_slam.onset_windows=five", r"filters\.a_slam\.onset_windows"),
    ("filters.a_slam.onset_window_probability=1.0", r"filters\.a_slam\.onset_window_probability"),
    ("filters.a_slam.onset_frame_quantile=1.5", r"filters\.a_slam\.onset_frame_quantile"),
    ("filters.a_slam.onset_frame_quantile=median", r"filters\.a_slam\.onset_frame_quantile"),
])
def test_a_slam_settings_reject_bad_values(override, match):
    with pytest.raises(ConfigError, match=match):
        a_slam_from_config(compose_config("dynamic_slam", [override]))
