"""Settings of ``+exp=marker_video`` (SPEC 17): the marker, its detection, the flip choice and the joint decision.

Every problem is one :class:`~stslam.errors.ConfigError` ``<key>: expected …``, raised before the video is read.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields, is_dataclass

from stslam.articulation.pose_decision import PoseDecisionSettings
from stslam.config.readers import get_bool, get_choice, get_float, get_int, get_optional, lookup
from stslam.errors import ConfigError
from stslam.markers.detect import DetectionSettings, check_dictionary_name

NOT_A_JOINT_POLICIES = ("refuse", "warn")


@dataclass(frozen=True)
class MarkerVideoSettings:
    """The run's inputs and choices (``conf/exp/marker_video.yaml``): files, marker side (m), ids (None: the
    most often seen marker; no reference), detection, flip choice (σ px, σ turn deg), decision, what to do
    with a track no joint explains, and the JPEG quality of scene.mcap's images."""

    video: str
    calib: str
    marker_length_m: float
    marker_id: int | None
    reference_id: int | None
    detection: DetectionSettings
    flip_sigma_px: float
    flip_sigma_turn_deg: float
    decision: PoseDecisionSettings
    not_a_joint: str
    jpeg_quality: int


def _path(cfg: Mapping, key: str) -> str:
    value = lookup(cfg, key, None)
    if not isinstance(value, str) or not value:
        raise ConfigError(f"{key}: expected a file path ({key}=<file>), got {value!r}")
    return value


def _block(cfg: Mapping, key: str, cls, **fixed):
    """``cls`` from the numbers at ``key.<field>``, or the block there for a field whose default is itself
    such settings (absent fields keep the dataclass defaults)."""
    block = lookup(cfg, key, {}) or {}
    if not isinstance(block, Mapping):
        raise ConfigError(f"{key}: expected a mapping of settings, got {block!r}")
    names = {f.name: f for f in fields(cls)}
    values = dict(fixed)
    for name in block:
        if name not in names or name in fixed:
            raise ConfigError(f"{key}.{name}: no such setting; expected one of "
                              f"{', '.join(n for n in names if n not in fixed)}")
        default = names[name].default
        if is_dataclass(default):
            values[name] = _block(cfg, f"{key}.{name}", type(default))
        elif isinstance(default, bool):
            values[name] = get_bool(cfg, f"{key}.{name}")
        elif isinstance(default, str):
            values[name] = lookup(cfg, f"{key}.{name}")
        elif isinstance(default, int) and not isinstance(default, bool):
            values[name] = get_int(cfg, f"{key}.{name}")
        else:
            values[name] = get_float(cfg, f"{key}.{name}")
    try:
        return cls(**values)
    except ValueError as error:
        raise ConfigError(f"{key}.{error}") from None


def marker_video_from_config(cfg: Mapping) -> MarkerVideoSettings:
    """:class:`MarkerVideoSettings` of the composed config (keys as in ``conf/exp/marker_video.yaml``)."""
    video, calib = _path(cfg, "video"), _path(cfg, "calib")
    length = lookup(cfg, "marker_length", None)
    if isinstance(length, bool) or not isinstance(length, (int, float)) or not length > 0:
        raise ConfigError(f"marker_length: expected the side of the marker's black square in metres, > 0 "
                          f"(e.g. marker_length=0.1), got {length!r}")
    name = lookup(cfg, "marker_dictionary", None)
    try:
        check_dictionary_name(name)
    except ValueError as error:
        raise ConfigError(f"marker_dictionary: {error}") from None
    marker_id, reference_id = (get_optional(get_int, cfg, "marker_id", low=0),
                              get_optional(get_int, cfg, "reference_id", low=0))
    if marker_id is not None and marker_id == reference_id:
        raise ConfigError(f"reference_id: expected a marker other than marker_id, got {reference_id} for both")
    return MarkerVideoSettings(
        video=video, calib=calib, marker_length_m=float(length), marker_id=marker_id, reference_id=reference_id,
        detection=_block(cfg, "detection", DetectionSettings, dictionary=name),
        flip_sigma_px=get_float(cfg, "flips.sigma_px", low=0.0, low_open=True),
        flip_sigma_turn_deg=get_float(cfg, "flips.sigma_turn_deg", low=0.0, low_open=True),
        decision=_block(cfg, "decision", PoseDecisionSettings),
        not_a_joint=get_choice(cfg, "not_a_joint", NOT_A_JOINT_POLICIES),
        jpeg_quality=get_int(cfg, "jpeg_quality", low=1, high=100))
