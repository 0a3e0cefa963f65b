"""Settings of ``experiments/convert.py``: a ROS bag to the SPEC 9 MCAP topics (SPEC 15).

Read from the ``conf/convert.yaml`` tree with :mod:`stslam.config.readers`;
every problem is one :class:`~stslam.errors.ConfigError` ``<key>: expected …``
raised before any file is opened.
"""

from __future__ import annotations

from pathlib import Path

from stslam.config.readers import get_bool, get_choice, get_float, get_float_list, get_int, get_optional, lookup
from stslam.errors import ConfigError
from stslam.io.bag_convert import OPTIONAL_TOPICS, TOPIC_KEYS, BagTopics, ConvertSettings
from stslam.io.rosbag_read import STAMP_SOURCES, UNORDERED_POLICIES


def _path(cfg, key: str, required: bool) -> str | None:
    value = lookup(cfg, key, None)
    if value is None and not required:
        return None
    if not isinstance(value, str) or not value:
        what = "a path" if required else "a path or null"
        raise ConfigError(f"{key}: expected {what}, got {value!r}")
    return value


def _name(cfg, key: str, optional: bool) -> str | None:
    value = lookup(cfg, key, None)
    if value is None and optional:
        return None
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{key}: expected a {'topic' if key.startswith('topics') else 'frame'} name"
                          f"{' or null' if optional else ''}, got {value!r}")
    return value


def convert_from_config(cfg) -> ConvertSettings:
    """:class:`ConvertSettings` of the config tree (keys as in ``conf/convert.yaml``)."""
    bag = _path(cfg, "bag", True)
    out = _path(cfg, "out", True)
    if not out.endswith(".mcap"):
        raise ConfigError(f"out: expected a file name ending in .mcap, got {out!r}")
    overwrite = get_bool(cfg, "overwrite", default=False)
    if Path(out).exists() and not overwrite:
        raise ConfigError(f"out: {out} already exists; pass overwrite=true to replace it")
    topics = BagTopics(**{key: _name(cfg, f"topics.{key}", key in OPTIONAL_TOPICS) for key in TOPIC_KEYS})
    tum = _path(cfg, "ground_truth_tum", False)
    if tum is not None and topics.ground_truth is not None:
        raise ConfigError("ground_truth_tum: give either a ground-truth topic (topics.ground_truth) or a TUM "
                          "file, not both; set topics.ground_truth=null to use the file")
    mount = None
    if lookup(cfg, "mount", None) is not None:
        mount = tuple(get_float_list(cfg, "mount", length=7))
        if sum(q * q for q in mount[3:]) < 1e-12:
            raise ConfigError(f"mount: expected x, y, z, qx, qy, qz, qw with a non-zero quaternion, got {list(mount)}")
    return ConvertSettings(
        bag=bag, out=out, overwrite=overwrite, topics=topics,
        base_frame=_name(cfg, "frames.base", False), camera_frame=_name(cfg, "frames.camera", True),
        ground_truth_tum=tum,
        max_depth_offset_s=get_float(cfg, "max_depth_offset_s", low=0.0, low_open=True),
        max_pose_offset_s=get_float(cfg, "max_pose_offset_s", low=0.0),
        stamps=get_choice(cfg, "stamps", STAMP_SOURCES, default="header"),
        unordered=get_choice(cfg, "unordered", UNORDERED_POLICIES, default="error"), mount=mount,
        width=get_optional(get_int, cfg, "width", low=16, high=8192),
        progress=get_bool(cfg, "progress", default=False))
