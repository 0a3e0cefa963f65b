"""Read any RGB-D MCAP with the topics of :mod:`stslam.io.mcap_topics` as time-aligned frames (SPEC 9).

Images are streamed: the file is read chunk by chunk and only the images
waiting to be paired are held in memory. The small topics (calibration,
poses, door) are read first in one pass and kept as arrays.

Alignment: each RGB image is paired with the depth image nearest in time,
within ``max_depth_offset_s`` (an RGB image without one is skipped and
counted); poses are interpolated at the RGB time (linear in translation,
spherical in rotation) and taken from the nearest end up to
``max_pose_offset_s`` outside their time span (else left out); the door angle
is interpolated the same way; calibration and camera mount are the latest at
or before the image (else the first). A calibration with non-zero distortion
coefficients has its images undistorted to the ideal pinhole with the same K
(:mod:`stslam.io.undistort`; depth is taken as aligned to colour).

Every problem with the file (missing topic, wrong schema, unknown encoding,
mismatched image sizes, time going backwards, truncated or corrupt data) is
raised as one :class:`~stslam.errors.InputFileError` naming the file, the
topic and the problem.
"""

from __future__ import annotations

import bisect
import os
from collections import deque
from dataclasses import dataclass

import numpy as np
from mcap.reader import SeekingReader
from mcap_protobuf.decoder import DecoderFactory

from stslam.io import mcap_topics as mt
from stslam.io import pixels
from stslam.io.mcap_errors import ROSBAG1_MAGIC, begins_with, reading, salvage_hint
from stslam.io.pose_track import PoseTrack, checked_pose
from stslam.io.undistort import Undistortion
from stslam.errors import InputFileError


@dataclass(frozen=True)
class DoorState:
    """Door ground truth: a point on the hinge axis (m, world), its unit direction, the angle (rad)
    and the unit direction from the hinge along the closed panel (world; the panel at angle φ lies
    along it turned by φ about the axis)."""

    hinge_point_world: np.ndarray
    hinge_axis_world: np.ndarray
    angle_rad: float
    closed_direction_world: np.ndarray


@dataclass
class RGBDFrame:
    """One time-aligned RGB-D frame.

    Attributes
    ----------
    t_s : float
        Time of the RGB image (s, the recording's clock).
    rgb : numpy.ndarray, shape (H, W, 3), uint8
    depth_m : numpy.ndarray, shape (H, W), float32
        Optical-axis depth (m), NaN where the sensor has no return.
    K : numpy.ndarray, shape (3, 3)
        Intrinsics (pixels), conventions of :mod:`stslam.robot.pinhole`.
    T_world_camera, T_world_base, T_world_base_odom, T_base_camera : numpy.ndarray (4, 4) or None
        Ground-truth camera and robot poses, odometry robot pose and camera mount, when recorded.
    door : DoorState or None
    """

    t_s: float
    rgb: np.ndarray
    depth_m: np.ndarray
    K: np.ndarray
    T_world_camera: np.ndarray | None = None
    T_world_base: np.ndarray | None = None
    T_world_base_odom: np.ndarray | None = None
    T_base_camera: np.ndarray | None = None
    door: DoorState | None = None


def _open_reader(handle, path) -> SeekingReader:
    # No record can be longer than the file: a damaged length field fails fast instead of allocating.
    return SeekingReader(handle, validate_crcs=True, decoder_factories=[DecoderFactory()],
                         record_size_limit=max(1, os.path.getsize(path)))


def _stamp_s(decoded, log_time_ns: int) -> float:
    if decoded.HasField("timestamp"):
        return decoded.timestamp.seconds + 1e-9 * decoded.timestamp.nanos
    return 1e-9 * log_time_ns


def pose_parts(schema: str, topic: str, decoded):
    """(stamped message, parent, child, quaternion, translation) of each pose a FrameTransform, a FrameTransforms or
    a PoseInFrame holds; a PoseInFrame is the pose in ``frame_id`` of the body the topic names, child
    ``<topic> pose``."""
    if schema == mt.SCHEMA_POSE_IN_FRAME:
        yield decoded, decoded.frame_id, f"{topic} pose", decoded.pose.orientation, decoded.pose.position
        return
    for transform in (decoded.transforms if schema == mt.SCHEMA_FRAME_TRANSFORMS else (decoded,)):
        yield transform, transform.parent_frame_id, transform.child_frame_id, transform.rotation, transform.translation


def _poses(path, topic: str, schema: str, decoded, log_time_ns: int):
    """(stamp s, parent, child, 4 × 4 pose) of each pose in a message (:func:`pose_parts`)."""
    for stamped, parent, child, q, p in pose_parts(schema, topic, decoded):
        yield (_stamp_s(stamped, log_time_ns), parent, child,
               checked_pose(q, p, path, f"topic {topic}: transform {parent} → {child}"))


class _Track(PoseTrack):
    """Time-stamped 4 × 4 transforms of one child frame, interpolated on demand."""

    def __init__(self, parent: str):
        super().__init__()
        self.parent = parent

    def latest(self, t: float) -> np.ndarray | None:
        """The last pose at or before ``t``, else the first (for fixed transforms)."""
        if not self.times:
            return None
        return self.poses[max(0, bisect.bisect_right(self.times, t) - 1)]


def _check_increasing(path, topic: str, key, t: float, last: dict) -> None:
    previous = last.get(key)
    if previous is not None and t <= previous:
        raise InputFileError(path, f"topic {topic}: time stamps must increase, got {t:.9f} s after {previous:.9f} s")
    last[key] = t


def _decode_rgb(path, topic: str, msg, schema: str) -> np.ndarray:
    if schema == mt.SCHEMA_COMPRESSED_IMAGE:
        return pixels.colour_from_compressed(msg.data, msg.format, path, topic)
    return pixels.colour_from_raw(msg.data, msg.width, msg.height, msg.step, msg.encoding, path, topic)


def _decode_depth(path, topic: str, msg, schema: str) -> np.ndarray:
    if schema == mt.SCHEMA_COMPRESSED_IMAGE:
        return pixels.depth_from_compressed(msg.data, msg.format, path, topic)[0]
    return pixels.depth_from_raw(msg.data, msg.width, msg.height, msg.step, msg.encoding, path, topic)[0]


class RGBDMcapReader:
    """An RGB-D MCAP checked on construction and iterated as :class:`RGBDFrame` (SPEC 9).

    Parameters
    ----------
    path : str or Path
    topics : stslam.io.mcap_topics.RGBDTopics
    max_depth_offset_s : float
        Largest time difference between paired RGB and depth images (s).
    max_pose_offset_s : float
        How far outside a pose topic's time span its end pose is still used (s).

    Attributes
    ----------
    n_rgb_messages : int
        RGB images in the file (the number of frames when all pair up).
    skipped : int
        RGB images left out for want of a depth image, after a full iteration.
    metadata : dict[str, dict[str, str]]
        The file's metadata records.
    """

    def __init__(self, path, topics: mt.RGBDTopics = mt.DEFAULT_TOPICS, max_depth_offset_s: float = 0.02,
                 max_pose_offset_s: float = 0.05):
        self.path = str(path)
        self.topics = topics
        self.max_depth_offset_s = float(max_depth_offset_s)
        self.max_pose_offset_s = float(max_pose_offset_s)
        self.skipped = 0
        if not os.path.isfile(self.path):
            if os.path.isdir(self.path):
                raise InputFileError(self.path, "a folder, not an MCAP file; a ROS 2 bag folder is converted first: "
                                                f"python experiments/convert.py bag={self.path} out=<new.mcap>")
            raise InputFileError(self.path, "no such file")
        if begins_with(self.path, ROSBAG1_MAGIC):
            raise InputFileError(self.path, "a ROS 1 bag, not an MCAP file: convert it first, python "
                                            f"experiments/convert.py bag={self.path} out=<new.mcap>")
        with open(self.path, "rb") as handle, reading(self.path):
            reader = _open_reader(handle, self.path)
            summary = reader.get_summary()
            if summary is None:
                raise InputFileError(self.path, f"MCAP has no summary section (unfinished recording?)"
                                                f"{salvage_hint(self.path)}")
            self._check_channels(summary)
            self.n_rgb_messages = int(summary.statistics.channel_message_counts.get(
                self._channel_ids[topics.rgb], 0)) if summary.statistics else 0
            self.metadata = {m.name: dict(m.metadata) for m in reader.iter_metadata()}
            self._read_side_topics(reader)

    def _check_channels(self, summary) -> None:
        by_topic = {}
        for channel in summary.channels.values():
            schema = summary.schemas.get(channel.schema_id)
            by_topic[channel.topic] = (channel, schema)
        ros = sorted({c.message_encoding for c, _ in by_topic.values()} & {"cdr", "ros1"})
        hint = (f"; its messages are ROS ones ({', '.join(ros)}): convert it first, python experiments/convert.py "
                f"bag={self.path} out=<new.mcap>" if ros else "")
        for topic in self.topics.required():
            if topic not in by_topic:
                present = ", ".join(sorted(by_topic)) or "none"
                rename = "" if hint else ("; a recording with other names is read with RGBDTopics (+exp=fridge: "
                                          "mcap_topics.*)")
                raise InputFileError(self.path, f"topic {topic}: missing (topics present: {present}){hint}{rename}")
        self._channel_ids, self._schemas = {}, {}
        for topic, expected in self.topics.schema_of().items():
            if topic not in by_topic:
                continue
            channel, schema = by_topic[topic]
            name = schema.name if schema is not None else "no schema"
            if schema is None or name not in expected or channel.message_encoding != "protobuf":
                raise InputFileError(self.path, f"topic {topic}: expected protobuf {' or '.join(expected)}, got "
                                                f"{channel.message_encoding} {name}{hint}")
            self._channel_ids[topic], self._schemas[topic] = channel.id, name

    def _read_side_topics(self, reader) -> None:
        t = self.topics
        side = [x for x in (t.calibration, t.ground_truth_base, t.ground_truth_camera, t.odometry,
                            t.camera_mount, t.door) if x in self._channel_ids]
        self._calibrations: list[tuple[float, np.ndarray, int, int, str, np.ndarray]] = []
        self._undistortions: dict[tuple, Undistortion] = {}  # per distinct calibration, made at its first frame
        self._tracks: dict[str, dict[str, _Track]] = {topic: {} for topic in side}
        last: dict = {}
        for _, channel, message, decoded in reader.iter_decoded_messages(topics=side, log_time_order=True):
            topic = channel.topic
            with reading(self.path, topic):
                if topic == t.calibration:
                    stamp = _stamp_s(decoded, message.log_time)
                    _check_increasing(self.path, topic, topic, stamp, last)
                    K = np.asarray(decoded.K, dtype=float)
                    if K.size != 9 or K[0] == 0 or not np.all(np.isfinite(K)):
                        raise InputFileError(self.path, f"topic {topic}: K must hold 9 finite numbers with "
                                                        f"fx ≠ 0, got {K.tolist()}")
                    self._calibrations.append((stamp, K.reshape(3, 3), decoded.width, decoded.height,
                                               decoded.distortion_model, np.asarray(decoded.D, dtype=float)))
                    continue
                for stamp, parent, child, T in _poses(self.path, topic, self._schemas[topic], decoded,
                                                      message.log_time):
                    _check_increasing(self.path, topic, (topic, child), stamp, last)
                    track = self._tracks[topic].setdefault(child, _Track(parent))
                    track.times.append(stamp)
                    track.poses.append(T)
        if not self._calibrations:
            raise InputFileError(self.path, f"topic {t.calibration}: no messages")
        self._calibration_times = [c[0] for c in self._calibrations]  # increasing (checked above), for bisect
        for topic, tracks in self._tracks.items():
            wanted = 2 if topic == t.door else 1
            if tracks and len(tracks) != wanted:
                raise InputFileError(self.path, f"topic {topic}: expected {wanted} child frame(s), got "
                                                f"{', '.join(sorted(tracks))}")
        self._door_tracks = self._door_hinge_and_panel()

    def _door_hinge_and_panel(self) -> tuple[_Track, _Track] | None:
        tracks = self._tracks.get(self.topics.door)
        if not tracks:
            return None
        (a, track_a), (b, track_b) = sorted(tracks.items())
        if track_b.parent == a:
            return track_a, track_b
        if track_a.parent == b:
            return track_b, track_a
        raise InputFileError(self.path, f"topic {self.topics.door}: expected a hinge transform and a panel "
                                        f"transform whose parent is the hinge frame, got {a} and {b}")

    def _pose(self, topic: str, t: float) -> np.ndarray | None:
        tracks = self._tracks.get(topic)
        if not tracks:
            return None
        return next(iter(tracks.values())).at(t, self.max_pose_offset_s)

    def _door(self, t: float) -> DoorState | None:
        if self._door_tracks is None:
            return None
        hinge, panel = self._door_tracks
        T_hinge = hinge.latest(t)
        T_panel = panel.at(t, self.max_pose_offset_s)
        if T_panel is None:
            return None
        # φ = rotation of the panel about the hinge z axis (SPEC 9 door encoding).
        angle = float(np.arctan2(T_panel[1, 0], T_panel[0, 0]))
        return DoorState(hinge_point_world=T_hinge[:3, 3].copy(), hinge_axis_world=T_hinge[:3, 2].copy(),
                         angle_rad=angle, closed_direction_world=T_hinge[:3, 0].copy())

    def _frame(self, t: float, rgb_msg, depth_msg) -> RGBDFrame:
        topics = self.topics
        rgb = _decode_rgb(self.path, topics.rgb, rgb_msg, self._schemas[topics.rgb])
        depth = _decode_depth(self.path, topics.depth, depth_msg, self._schemas[topics.depth])
        if depth.shape != rgb.shape[:2]:
            raise InputFileError(self.path, f"topic {topics.depth}: depth image is {depth.shape[1]} × "
                                            f"{depth.shape[0]} but {topics.rgb} is {rgb.shape[1]} × {rgb.shape[0]}")
        index = max(0, bisect.bisect_right(self._calibration_times, t) - 1)
        _, K, width, height, model, D = self._calibrations[index]
        if (width, height) != (rgb.shape[1], rgb.shape[0]) and (width, height) != (0, 0):
            raise InputFileError(self.path, f"topic {topics.calibration}: calibration is for {width} × {height} "
                                            f"images but {topics.rgb} is {rgb.shape[1]} × {rgb.shape[0]}")
        key = (K.tobytes(), model, D.tobytes(), rgb.shape[:2])  # a calibration repeated per frame: one map
        if key not in self._undistortions:  # images with lens distortion become the ideal pinhole's
            self._undistortions[key] = Undistortion(K, model, D, (rgb.shape[1], rgb.shape[0]), self.path,
                                                    topics.calibration)
        fix = self._undistortions[key]
        rgb, depth = fix.colour(rgb), fix.depth(depth)
        mount = self._tracks.get(topics.camera_mount)
        T_base_camera = next(iter(mount.values())).latest(t) if mount else None
        T_world_base = self._pose(topics.ground_truth_base, t)
        T_world_camera = self._pose(topics.ground_truth_camera, t)
        if T_world_camera is None and T_world_base is not None and T_base_camera is not None:
            T_world_camera = T_world_base @ T_base_camera
        return RGBDFrame(t_s=t, rgb=rgb, depth_m=depth, K=K.copy(), T_world_camera=T_world_camera,
                         T_world_base=T_world_base, T_world_base_odom=self._pose(topics.odometry, t),
                         T_base_camera=T_base_camera, door=self._door(t))

    def _pair_ready(self, pending: deque, depths: deque, last_depth_t: float, final: bool):
        tol = self.max_depth_offset_s
        while pending and (final or last_depth_t >= pending[0][0] + tol):
            t, rgb_msg = pending.popleft()
            while depths and depths[0][0] < t - tol:
                depths.popleft()
            best = min(depths, key=lambda d: abs(d[0] - t), default=None)
            if best is None or abs(best[0] - t) > tol:
                self.skipped += 1
                continue
            yield self._frame(t, rgb_msg, best[1])

    def __iter__(self):
        topics = self.topics
        self.skipped = 0
        pending: deque = deque()
        depths: deque = deque()
        last_depth_t = -np.inf
        last: dict = {}
        n_frames = 0
        with open(self.path, "rb") as handle, reading(self.path, f"{topics.rgb} or {topics.depth}"):
            reader = _open_reader(handle, self.path)
            for _, channel, message, decoded in reader.iter_decoded_messages(
                    topics=[topics.rgb, topics.depth], log_time_order=True):
                t = _stamp_s(decoded, message.log_time)
                _check_increasing(self.path, channel.topic, channel.topic, t, last)
                if channel.topic == topics.rgb:
                    pending.append((t, decoded))
                else:
                    depths.append((t, decoded))
                    last_depth_t = t
                for frame in self._pair_ready(pending, depths, last_depth_t, final=False):
                    n_frames += 1
                    yield frame
            for frame in self._pair_ready(pending, depths, last_depth_t, final=True):
                n_frames += 1
                yield frame
        if n_frames == 0:
            if topics.rgb not in last:
                raise InputFileError(self.path, f"topic {topics.rgb}: no messages")
            raise InputFileError(self.path, f"topic {topics.depth}: no depth image within "
                                            f"{self.max_depth_offset_s} s of any {topics.rgb} image")


def read_rgbd_frames(path, **options):
    """Iterate over the time-aligned frames of an RGB-D MCAP (see :class:`RGBDMcapReader`)."""
    return iter(RGBDMcapReader(path, **options))
