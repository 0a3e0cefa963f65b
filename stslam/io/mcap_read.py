"""Read any RGB-D MCAP with the topics of :mod:`stslam.io.mcap_topics` as time-aligned frames (SPEC 9).

Images are streamed: the file is read chunk by chunk, once, and only the
images waiting to be paired are held in memory. The small topics (calibration,
poses, door) are gathered in the same pass (:mod:`stslam.io.mcap_side`); a
paired frame waits until they have all reached past its time, so a frame gets
what it would get were they read first in a pass of their own.

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

import os
from collections import deque
from dataclasses import dataclass

import numpy as np
from mcap.reader import SeekingReader
from mcap_protobuf.decoder import DecoderFactory

from stslam.io import mcap_topics as mt
from stslam.io import pixels
from stslam.io.mcap_errors import ROSBAG1_MAGIC, begins_with, reading, salvage_hint
from stslam.io.mcap_side import SideTopics, check_increasing, stamp_s
from stslam.io.undistort import Undistortion
from stslam.errors import InputFileError

MAX_WAITING = 30  # paired frames held for the small topics before these are read in a pass of their own


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
            self._side_counts = self._counts(summary)
            self._side = SideTopics(self.path, topics, self._side_schemas(), self._side_counts)
        self._undistortions: dict[tuple, Undistortion] = {}  # per distinct calibration, made at its first frame

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

    def _side_schemas(self) -> dict:
        rgb, depth = self.topics.rgb, self.topics.depth
        return {topic: name for topic, name in self._schemas.items() if topic not in (rgb, depth)}

    def _counts(self, summary) -> dict | None:
        """Messages per small topic from the summary statistics (over every channel of the topic), or None."""
        if summary.statistics is None:
            return None
        counts = summary.statistics.channel_message_counts
        out = dict.fromkeys(self._side_schemas(), 0)
        for channel in summary.channels.values():
            if channel.topic in out:
                out[channel.topic] += int(counts.get(channel.id, 0))
        return out

    def _full_side_pass(self) -> SideTopics:
        """Every small topic's messages, read in a pass of their own."""
        side = SideTopics(self.path, self.topics, self._side_schemas(), self._side_counts)
        with open(self.path, "rb") as handle, reading(self.path):
            reader = _open_reader(handle, self.path)
            for _, channel, message, decoded in reader.iter_decoded_messages(topics=side.names, log_time_order=True):
                side.add(channel.topic, decoded, message.log_time)
        side.finish()
        return side

    def _door(self, side: SideTopics, t: float) -> DoorState | None:
        door = side.door_tracks()
        if door is None:
            return None
        hinge, panel = door
        T_hinge = hinge.latest(t)
        T_panel = panel.at(t, self.max_pose_offset_s)
        if T_panel is None:
            return None
        # φ = rotation of the panel about the hinge z axis (SPEC 9 door encoding).
        angle = float(np.arctan2(T_panel[1, 0], T_panel[0, 0]))
        return DoorState(hinge_point_world=T_hinge[:3, 3].copy(), hinge_axis_world=T_hinge[:3, 2].copy(),
                         angle_rad=angle, closed_direction_world=T_hinge[:3, 0].copy())

    def _frame(self, side: SideTopics, t: float, rgb_msg, depth_msg) -> RGBDFrame:
        topics = self.topics
        rgb = _decode_rgb(self.path, topics.rgb, rgb_msg, self._schemas[topics.rgb])
        depth = _decode_depth(self.path, topics.depth, depth_msg, self._schemas[topics.depth])
        if depth.shape != rgb.shape[:2]:
            raise InputFileError(self.path, f"topic {topics.depth}: depth image is {depth.shape[1]} × "
                                            f"{depth.shape[0]} but {topics.rgb} is {rgb.shape[1]} × {rgb.shape[0]}")
        _, K, width, height, model, D = side.calibration(t)
        if (width, height) != (rgb.shape[1], rgb.shape[0]) and (width, height) != (0, 0):
            raise InputFileError(self.path, f"topic {topics.calibration}: calibration is for {width} × {height} "
                                            f"images but {topics.rgb} is {rgb.shape[1]} × {rgb.shape[0]}")
        key = (K.tobytes(), model, D.tobytes(), rgb.shape[:2])  # a calibration repeated per frame: one map
        if key not in self._undistortions:  # images with lens distortion become the ideal pinhole's
            self._undistortions[key] = Undistortion(K, model, D, (rgb.shape[1], rgb.shape[0]), self.path,
                                                    topics.calibration)
        fix = self._undistortions[key]
        rgb, depth = fix.colour(rgb), fix.depth(depth)
        offset = self.max_pose_offset_s
        T_base_camera = side.latest(topics.camera_mount, t)
        T_world_base = side.pose(topics.ground_truth_base, t, offset)
        T_world_camera = side.pose(topics.ground_truth_camera, t, offset)
        if T_world_camera is None and T_world_base is not None and T_base_camera is not None:
            T_world_camera = T_world_base @ T_base_camera
        return RGBDFrame(t_s=t, rgb=rgb, depth_m=depth, K=K.copy(), T_world_camera=T_world_camera,
                         T_world_base=T_world_base, T_world_base_odom=side.pose(topics.odometry, t, offset),
                         T_base_camera=T_base_camera, door=self._door(side, t))

    def _pair_ready(self, pending: deque, depths: deque, last_depth_t: float, final: bool):
        """(t, RGB message, depth message) of each RGB image whose nearest depth image is known."""
        tol = self.max_depth_offset_s
        while pending and (final or last_depth_t >= pending[0][0] + tol):
            t, rgb_msg = pending.popleft()
            while depths and depths[0][0] < t - tol:
                depths.popleft()
            best = min(depths, key=lambda d: abs(d[0] - t), default=None)
            if best is None or abs(best[0] - t) > tol:
                self.skipped += 1
                continue
            yield t, rgb_msg, best[1]

    def __iter__(self):
        """The frames, in one pass over the file: the small topics are gathered as they come, and a paired
        frame waits until they have all reached past its time (:meth:`SideTopics.settled`). Should more than
        ``MAX_WAITING`` frames wait (a small topic stamped far behind its log time, or without summary
        statistics), the small topics are read in a pass of their own instead."""
        topics = self.topics
        self.skipped = 0
        if not self._side.complete:  # (after a complete iteration, later ones reuse what it gathered)
            self._side = SideTopics(self.path, topics, self._side_schemas(), self._side_counts)
        side = self._side
        pending: deque = deque()
        depths: deque = deque()
        ready: deque = deque()  # paired, waiting for the small topics
        last_depth_t = -np.inf
        last: dict = {}
        n_frames = 0
        wanted = [topics.rgb, topics.depth] + ([] if side.complete else side.names)
        with open(self.path, "rb") as handle, reading(self.path, f"{topics.rgb} or {topics.depth}"):
            reader = _open_reader(handle, self.path)
            for _, channel, message, decoded in reader.iter_decoded_messages(topics=wanted, log_time_order=True):
                topic = channel.topic
                if topic not in (topics.rgb, topics.depth):
                    if not side.complete:
                        side.add(topic, decoded, message.log_time)
                else:
                    t = stamp_s(decoded, message.log_time)
                    check_increasing(self.path, topic, topic, t, last)
                    if topic == topics.rgb:
                        pending.append((t, decoded))
                    else:
                        depths.append((t, decoded))
                        last_depth_t = t
                    ready.extend(self._pair_ready(pending, depths, last_depth_t, final=False))
                    if len(ready) > MAX_WAITING and not side.complete:
                        side = self._side = self._full_side_pass()
                while ready and side.settled(ready[0][0]):
                    n_frames += 1
                    yield self._frame(side, *ready.popleft())
            ready.extend(self._pair_ready(pending, depths, last_depth_t, final=True))
            if not side.complete:
                side.finish()
            while ready:
                n_frames += 1
                yield self._frame(side, *ready.popleft())
        if n_frames == 0:
            if topics.rgb not in last:
                raise InputFileError(self.path, f"topic {topics.rgb}: no messages")
            raise InputFileError(self.path, f"topic {topics.depth}: no depth image within "
                                            f"{self.max_depth_offset_s} s of any {topics.rgb} image")


def read_rgbd_frames(path, **options):
    """Iterate over the time-aligned frames of an RGB-D MCAP (see :class:`RGBDMcapReader`)."""
    return iter(RGBDMcapReader(path, **options))
