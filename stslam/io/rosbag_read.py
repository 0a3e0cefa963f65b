"""Messages of a ROS 1 or ROS 2 bag as arrays, with the ``rosbags`` library (SPEC 15).

No ROS install is needed: :class:`rosbags.highlevel.AnyReader` reads ROS 1
``.bag`` files and ROS 2 bag folders (sqlite3 or MCAP storage) with the
message definitions they carry. Every problem with the bag (unreadable file,
missing topic, wrong message type, time stamps going back, an image that
cannot be decoded) is one :class:`~stslam.errors.InputFileError` naming the
bag and the topic.

Conventions: a stamp is the message header's ``stamp`` in seconds (ROS time,
``sec + 1e-9 nanosec``); a pose is a 4 × 4 matrix X_parent = R X_child + t.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

import numpy as np

from stslam.io import pixels
from stslam.io.mcap_errors import begins_as_mcap
from stslam.io.pose_track import checked_pose
from stslam.errors import InputFileError, StslamError

IMAGE = "sensor_msgs/msg/Image"
COMPRESSED = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"
ODOMETRY = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TRANSFORM_STAMPED = "geometry_msgs/msg/TransformStamped"
IMAGE_TYPES = (IMAGE, COMPRESSED)
GROUND_TRUTH_TYPES = (POSE_STAMPED, TRANSFORM_STAMPED, ODOMETRY)


@contextlib.contextmanager
def open_bag(path):
    """An open :class:`rosbags.highlevel.AnyReader` of the bag at ``path`` (a file or a ROS 2 folder)."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    path = Path(path)
    if not path.exists():
        raise InputFileError(path, "no such bag file or folder")
    try:
        reader = AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except StslamError:
        raise
    except Exception as error:  # rosbags raises its own error types for every kind of damage
        text = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise InputFileError(path, f"not a readable ROS 1 or ROS 2 bag ({type(error).__name__}: {text})"
                                   f"{_damage_hint(path)}") from None
    try:
        yield reader
    finally:
        reader.close()


def _damage_hint(path: Path) -> str:
    """What to try with a ROS 2 recording cut short: its MCAP file salvaged, or given on its own when the
    folder has no metadata.yaml (a recorder killed before writing it)."""
    if path.is_dir() and not (path / "metadata.yaml").exists():
        return ("; a ROS 2 folder without metadata.yaml (its recorder stopped before writing it): pass its .mcap "
                "or .db3 file as bag=, an .mcap cut short after python experiments/salvage_mcap.py <file> <new.mcap>")
    if path.is_file() and begins_as_mcap(path):
        return (f"; if the recording was cut short: python experiments/salvage_mcap.py {path} <new.mcap>, "
                f"then bag=<new.mcap>")
    return ""


def connections_of(reader, path, topic: str, types: tuple[str, ...], required: bool = True) -> list:
    """The bag's connections of ``topic``, checked to carry one of ``types``; [] if absent and optional."""
    found = [c for c in reader.connections if c.topic == topic]
    if not found:
        if not required:
            return []
        present = ", ".join(sorted({c.topic for c in reader.connections})) or "none"
        raise InputFileError(path, f"topic {topic}: missing (topics present: {present})")
    for c in found:
        if c.msgtype not in types:
            raise InputFileError(path, f"topic {topic}: expected {' or '.join(types)}, got {c.msgtype}")
    return found


def messages(reader, path, connections: list):
    """(topic, message type, decoded message, receive time in ns) of ``connections`` in bag order; damage
    named by topic."""
    if not connections:  # rosbags reads every connection when given none
        return
    iterator = reader.messages(connections=connections)
    while True:
        try:
            connection, received_ns, raw = next(iterator)
        except StopIteration:
            return
        except Exception as error:
            raise InputFileError(path, f"topics {', '.join(c.topic for c in connections)}: bag data "
                                       f"unreadable ({type(error).__name__}: {error})") from None
        try:
            decoded = reader.deserialize(raw, connection.msgtype)
        except Exception as error:
            raise InputFileError(path, f"topic {connection.topic}: message cannot be decoded as "
                                       f"{connection.msgtype} ({type(error).__name__}: {error})") from None
        yield connection.topic, connection.msgtype, decoded, int(received_ns)


def stamp_s(header) -> float:
    """Seconds of a header's stamp."""
    return float(header.stamp.sec) + 1e-9 * float(header.stamp.nanosec)


STAMP_SOURCES = ("header", "receive")
UNORDERED_POLICIES = ("error", "drop")


class Stamps:
    """A message's time, from its header's stamp or from when the bag received it (``source``), checked
    to increase per topic; a message whose time does not (a repeated frame, one out of order) stops the
    reading (``unordered="error"``) or is left out and counted (``"drop"``)."""

    def __init__(self, path, source: str = "header", unordered: str = "error"):
        if source not in STAMP_SOURCES:
            raise ValueError(f"stamps: expected one of {', '.join(STAMP_SOURCES)}; got {source!r}")
        if unordered not in UNORDERED_POLICIES:
            raise ValueError(f"unordered: expected one of {', '.join(UNORDERED_POLICIES)}; got {unordered!r}")
        self.path, self.source, self.unordered = path, source, unordered
        self.last: dict = {}
        self.dropped: dict[str, int] = {}

    def of(self, topic: str, msg, received_ns: int) -> float | None:
        """The time (s) of ``msg``, received at ``received_ns``, or None when it does not increase and is dropped."""
        t = stamp_s(msg.header) if self.source == "header" else 1e-9 * received_ns
        previous = self.last.get(topic)
        if previous is not None and t <= previous:
            if self.unordered == "drop":
                self.dropped[topic] = self.dropped.get(topic, 0) + 1
                return None
            unset = t == previous == 0
            hint = ("; pass stamps=receive to use the times the bag recorded the messages" if unset and
                    self.source == "header" else "; pass unordered=drop to leave such messages out")
            cause = " (header stamps of 0: the publisher did not stamp its messages)" if unset else ""
            raise InputFileError(self.path, f"topic {topic}: time stamps must increase, got {t:.9f} s after "
                                            f"{previous:.9f} s{cause}{hint}")
        self.last[topic] = t
        return t


def pose_of(msg, msgtype: str, path, topic: str) -> np.ndarray:
    """4 × 4 pose of a PoseStamped, TransformStamped or Odometry message (child in parent)."""
    if msgtype == POSE_STAMPED:
        return checked_pose(msg.pose.orientation, msg.pose.position, path, f"topic {topic}: pose")
    if msgtype == ODOMETRY:
        return checked_pose(msg.pose.pose.orientation, msg.pose.pose.position, path, f"topic {topic}: pose")
    return checked_pose(msg.transform.rotation, msg.transform.translation, path, f"topic {topic}: pose")


def intrinsics_of(msg, path, topic: str) -> tuple[np.ndarray, int, int]:
    """K (3 × 3), width and height of the images a CameraInfo describes (ROS 2 field ``k``, ROS 1 ``K``); K must
    be finite with fx ≠ 0 (else InputFileError naming ``topic``).

    K, width and height are the full sensor's; images cut to a region of interest and binned (REP 104:
    ``roi``, ``binning_x``/``binning_y``, 0 or 1 for none) have x′ = (x − x_offset) / binning_x, so
    f′ = f / binning and c′ = (c − offset) / binning (as ROS's image_geometry takes them), and the size of
    the region (else the sensor) divided by the binning. Distortion acts on normalised coordinates and
    is unchanged.
    """
    K = np.asarray(msg.k if hasattr(msg, "k") else msg.K, dtype=float).reshape(3, 3)
    if K[0, 0] == 0 or not np.all(np.isfinite(K)):
        raise InputFileError(path, f"topic {topic}: K must be finite with fx ≠ 0, got {K.tolist()}")
    bx, by = max(1, int(msg.binning_x)), max(1, int(msg.binning_y))
    roi = msg.roi
    cropped = int(roi.width) > 0 and int(roi.height) > 0
    x0, y0 = (int(roi.x_offset), int(roi.y_offset)) if cropped else (0, 0)
    width, height = (int(roi.width), int(roi.height)) if cropped else (int(msg.width), int(msg.height))
    if (bx, by, x0, y0) == (1, 1, 0, 0):
        return K, width, height
    K = K.copy()
    K[0, :] = [K[0, 0] / bx, K[0, 1] / bx, (K[0, 2] - x0) / bx]
    K[1, 1:] = [K[1, 1] / by, (K[1, 2] - y0) / by]
    return K, width // bx, height // by


def distortion_of(msg) -> tuple[str, np.ndarray]:
    """Distortion model name and coefficients of a CameraInfo (ROS 2 field ``d``, ROS 1 ``D``)."""
    D = np.asarray(msg.d if hasattr(msg, "d") else msg.D, dtype=float).reshape(-1)
    return str(msg.distortion_model), D


def colour_of(msg, msgtype: str, path, topic: str) -> np.ndarray:
    """uint8 (H, W, 3) RGB of an Image or a CompressedImage (:mod:`stslam.io.pixels` for the encodings)."""
    if msgtype == COMPRESSED:
        return pixels.colour_from_compressed(msg.data, str(msg.format), path, topic)
    return pixels.colour_from_raw(msg.data, msg.width, msg.height, msg.step, str(msg.encoding), path, topic)


def depth_of(msg, msgtype: str, path, topic: str) -> tuple[np.ndarray, str]:
    """Depth (H, W) float32 metres (NaN = no return) and the source encoding (16UC1 or 32FC1)."""
    if msgtype == COMPRESSED:
        return pixels.depth_from_compressed(msg.data, str(msg.format), path, topic)
    return pixels.depth_from_raw(msg.data, msg.width, msg.height, msg.step, str(msg.encoding), path, topic,
                                 big_endian=bool(msg.is_bigendian))


def chain(edges: dict, parent: str, child: str) -> np.ndarray | None:
    """Pose of ``child`` in ``parent`` from TF ``edges`` {child: (parent, 4 × 4)}, or None when not connected."""
    T = np.eye(4)
    frame = child
    seen = set()
    while frame != parent:
        if frame not in edges or frame in seen:
            return None
        seen.add(frame)
        up, T_up = edges[frame]
        T = T_up @ T
        frame = up
    return T


def tf_edges(msg, path, topic: str) -> dict:
    """{child: (parent, 4 × 4)} of one TFMessage (frame names without a leading '/')."""
    out = {}
    for transform in msg.transforms:
        child = transform.child_frame_id.lstrip("/")
        out[child] = (transform.header.frame_id.lstrip("/"),
                      checked_pose(transform.transform.rotation, transform.transform.translation, path,
                                   f"topic {topic}: transform {transform.header.frame_id} → {child}"))
    return out
