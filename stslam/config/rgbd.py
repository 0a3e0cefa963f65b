"""The fridge experiment's front end and sequence, and the data sets of ``make_data``, from their config blocks.

``frontend`` (``conf/exp/fridge.yaml``) gives the tracker's settings (SPEC 8.5);
a data config (``conf/data/fridge.yaml``, also the fridge experiment's
``sequence`` block) the rendered sequence (SPEC 9) and, with ``make_data``'s
top-level keys, the :class:`~stslam.rgbd.sequence.DataRequest`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from stslam.config.readers import field_default, get_bool, get_choice, get_float, get_float_list, get_int, lookup
from stslam.errors import ConfigError
from stslam.io.mcap_topics import DEFAULT_TOPICS, DEPTH_WRITE_ENCODINGS, RGBDTopics
from stslam.rgbd.frontend import TrackerSettings
from stslam.rgbd.sequence import DataRequest, SequenceConfig

# The data sets ``make_data +data=<name>`` knows (one config file each in conf/data/).
DATASETS = ("fridge",)


def tracker_from_config(cfg: Mapping, key: str = "frontend") -> TrackerSettings:
    """Checked :class:`~stslam.rgbd.frontend.TrackerSettings` from the block at ``key`` (ConfigError)."""
    depth_min = get_float(cfg, f"{key}.depth_min_m", low=0.0, low_open=True)
    return TrackerSettings(
        target_tracks=get_int(cfg, f"{key}.target_tracks", low=1, high=100000),
        redetect_fraction=get_float(cfg, f"{key}.redetect_fraction", low=0.0, high=1.0),
        quality_level=get_float(cfg, f"{key}.quality_level", low=0.0, high=1.0, low_open=True, high_open=True),
        grid_cols=get_int(cfg, f"{key}.grid_cols", low=1, high=64),
        grid_rows=get_int(cfg, f"{key}.grid_rows", low=1, high=64),
        min_distance_px=get_float(cfg, f"{key}.min_distance_px", low=1.0, high=1000.0),
        block_size=get_int(cfg, f"{key}.block_size", low=3, high=31),
        window_px=get_int(cfg, f"{key}.window_px", low=5, high=101),
        pyramid_levels=get_int(cfg, f"{key}.pyramid_levels", low=0, high=8),
        fb_max_px=get_float(cfg, f"{key}.fb_max_px", low=0.0, low_open=True),
        depth_half_window_px=get_int(cfg, f"{key}.depth_half_window_px", low=0, high=10),
        depth_min_m=depth_min,
        depth_max_m=get_float(cfg, f"{key}.depth_max_m", low=depth_min, low_open=True),
        max_depth_spread_m=get_float(cfg, f"{key}.max_depth_spread_m", low=0.0, low_open=True),
        max_jump_m=get_float(cfg, f"{key}.max_jump_m", low=0.0, low_open=True),
        pixel_sigma_px=get_float(cfg, f"{key}.pixel_sigma_px", low=0.0, low_open=True),
        depth_noise_coefficient=get_float(cfg, f"{key}.depth_noise_coefficient", low=0.0, low_open=True),
    )


def topics_from_config(cfg: Mapping, key: str = "mcap_topics") -> RGBDTopics:
    """A recording's topic names (:class:`~stslam.io.mcap_topics.RGBDTopics`) from the block at ``key``; a name
    left out keeps its default, one that is not a topic name raises ConfigError."""
    block = lookup(cfg, key, None)
    if block is None:
        return DEFAULT_TOPICS
    if not isinstance(block, Mapping):
        raise ConfigError(f"{key}: expected a block of topic names, got {block!r}")
    names = list(vars(DEFAULT_TOPICS))
    unknown = sorted(set(block) - set(names))
    if unknown:
        raise ConfigError(f"{key}.{unknown[0]}: unknown; expected one of {', '.join(names)}")
    for name, value in block.items():
        if not isinstance(value, str) or not value:
            raise ConfigError(f"{key}.{name}: expected a topic name, got {value!r}")
    topics = RGBDTopics(**{name: block.get(name, getattr(DEFAULT_TOPICS, name)) for name in names})
    used = [getattr(topics, name) for name in names]
    repeated = sorted({t for t in used if used.count(t) > 1})
    if repeated:
        raise ConfigError(f"{key}: topic {repeated[0]} is given for more than one of {', '.join(names)}")
    return topics


def sequence_from_config(cfg: Mapping) -> SequenceConfig:
    """Checked :class:`~stslam.rgbd.sequence.SequenceConfig` from a data config (``conf/data/fridge.yaml``):
    top-level ``n_frames, width, height, rate_hz`` and the ``fridge.*`` block; a bad value raises ConfigError."""
    door_times = get_float_list(cfg, "fridge.door_times", length=4, low=0.0)
    if not all(a < b for a, b in zip(door_times, door_times[1:])) or door_times[-1] > 1.0:
        raise ConfigError(f"fridge.door_times: expected 4 increasing fractions in [0, 1], got {door_times}")
    depth_min_m = get_float(cfg, "fridge.depth_min_m", low=0.0)
    depth_max_m = get_float(cfg, "fridge.depth_max_m", low=depth_min_m, low_open=True)
    return SequenceConfig(
        n_frames=get_int(cfg, "n_frames", low=1),
        width=get_int(cfg, "width", low=16, high=8192),
        height=get_int(cfg, "height", low=16, high=8192),
        rate_hz=get_float(cfg, "rate_hz", low=0.0, low_open=True, high=1000.0),
        hfov_deg=get_float(cfg, "fridge.hfov_deg", low=10.0, high=150.0),
        camera_height_m=get_float(cfg, "fridge.camera_height_m", low=0.1, high=2.5),
        camera_yaw_deg=get_float(cfg, "fridge.camera_yaw_deg", low=-180.0, high=180.0),
        path_radius_m=get_float(cfg, "fridge.path_radius_m", low=0.8, high=3.0),
        path_radius_swing_m=get_float(cfg, "fridge.path_radius_swing_m", low=0.0, high=0.5),
        path_start_deg=get_float(cfg, "fridge.path_start_deg", low=-80.0, high=80.0),
        path_end_deg=get_float(cfg, "fridge.path_end_deg", low=-80.0, high=80.0),
        door_open_deg=get_float(cfg, "fridge.door_open_deg", low=0.0, high=120.0),
        door_times=tuple(door_times),
        alpha=tuple(get_float_list(cfg, "fridge.alpha", length=4, low=0.0)),
        depth_noise_coefficient=get_float(cfg, "fridge.depth_noise_coefficient", low=0.0),
        depth_min_m=depth_min_m,
        depth_max_m=depth_max_m,
        max_incidence_deg=get_float(cfg, "fridge.max_incidence_deg", low=0.0, high=90.0),
        rgb_noise_std=get_float(cfg, "fridge.rgb_noise_std", low=0.0, high=50.0),
    )


def data_request_from_config(cfg: Mapping) -> DataRequest:
    """The data set named by ``data_name``, every value checked before any work (ConfigError)."""
    name = lookup(cfg, "data_name", None)
    if name is None:
        raise ConfigError("data: no data set chosen; add +data=<name> with one of " + ", ".join(DATASETS))
    get_choice(cfg, "data_name", DATASETS)
    seed = get_int(cfg, "seed", low=0)
    out = lookup(cfg, "out", None)
    if not isinstance(out, str) or not out:
        raise ConfigError(f"out: expected an output file name, got {out!r}")
    overwrite = get_bool(cfg, "overwrite")
    show_progress = get_bool(cfg, "progress", default=field_default(DataRequest, "show_progress"))
    encoding = get_choice(cfg, "depth_encoding", DEPTH_WRITE_ENCODINGS)
    return DataRequest(seed=seed, out=Path(out), sequence=sequence_from_config(cfg), depth_encoding=encoding,
                       overwrite=overwrite, show_progress=show_progress)
