"""Settings of ``experiments/convert.py``: a ROS bag to the SPEC 9 MCAP topics (SPEC 15).

Read from the ``conf/convert.yaml`` tree with :mod:`stslam.config.readers`;
every problem is one :class:`~stslam.errors.ConfigError` ``<key>: expected …``
raised before any file is opened.
"""

from __future__ import annotations

from dataclasses import dataclass

from stslam.config.readers import get_bool, get_float, lookup
from stslam.errors import ConfigError

TOPIC_KEYS = ("rgb", "depth", "camera_info", "odometry", "tf_static", "tf", "ground_truth")
OPTIONAL_TOPICS = ("tf", "ground_truth")


@dataclass(frozen=True)
class BagTopics:
    """Topic names in the bag (defaults: a RealSense camera on a wheeled robot, SPEC 15).

    ``ground_truth`` and ``tf`` may be ``None``; the others are required.
    """

    rgb: str = "/camera/color/image_raw"
    depth: str = "/camera/aligned_depth_to_color/image_raw"
    camera_info: str = "/camera/color/camera_info"
    odometry: str = "/odom"
    tf_static: str = "/tf_static"
    tf: str | None = "/tf"
    ground_truth: str | None = "/mocap/base"


@dataclass(frozen=True)
class ConvertSettings:
    """What to convert and how.

    Attributes
    ----------
    bag : str
        A ROS 1 ``.bag`` file or a ROS 2 bag folder (sqlite3 or MCAP storage).
    out : str
        The MCAP to write (SPEC 9 topics).
    overwrite : bool
        Replace an existing ``out``.
    topics : BagTopics
    base_frame : str
        The robot's body frame; the camera mount is the TF chain from it to the colour image's frame.
    camera_frame : str or None
        Frame of the colour images (None: the ``frame_id`` of their headers).
    ground_truth_tum : str or None
        A TUM file with the robot's true poses (instead of a ground-truth topic).
    max_depth_offset_s : float
        Largest stamp difference between a colour image and its depth image (s).
    max_pose_offset_s : float
        How far outside the odometry or ground truth time span a frame may lie and still take its end pose (s).
    progress : bool
    """

    bag: str
    out: str
    overwrite: bool = False
    topics: BagTopics = BagTopics()
    base_frame: str = "base_link"
    camera_frame: str | None = None
    ground_truth_tum: str | None = None
    max_depth_offset_s: float = 0.02
    max_pose_offset_s: float = 0.05
    progress: bool = False


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


def convert_settings_from(cfg) -> ConvertSettings:
    """:class:`ConvertSettings` of the config tree (keys as in ``conf/convert.yaml``)."""
    bag = _path(cfg, "bag", True)
    out = _path(cfg, "out", True)
    if not out.endswith(".mcap"):
        raise ConfigError(f"out: expected a file name ending in .mcap, got {out!r}")
    topics = BagTopics(**{key: _name(cfg, f"topics.{key}", key in OPTIONAL_TOPICS) for key in TOPIC_KEYS})
    tum = _path(cfg, "ground_truth_tum", False)
    if tum is not None and topics.ground_truth is not None:
        raise ConfigError("ground_truth_tum: give either a ground-truth topic (topics.ground_truth) or a TUM "
                          "file, not both; set topics.ground_truth=null to use the file")
    return ConvertSettings(
        bag=bag, out=out, overwrite=get_bool(cfg, "overwrite", default=False), topics=topics,
        base_frame=_name(cfg, "frames.base", False), camera_frame=_name(cfg, "frames.camera", True),
        ground_truth_tum=tum,
        max_depth_offset_s=get_float(cfg, "max_depth_offset_s", low=0.0, low_open=True),
        max_pose_offset_s=get_float(cfg, "max_pose_offset_s", low=0.0),
        progress=get_bool(cfg, "progress", default=False))
