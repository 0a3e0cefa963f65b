"""Write an RGB-D sequence as one MCAP file with Foxglove protobuf schemas (SPEC 9).

Topics, frames and encodings are defined in :mod:`stslam.io.mcap_topics`.

Byte-identical output for the same sequence: log and publish times come from
the sequence (never the wall clock), the header's library field is the fixed
:data:`LIBRARY` string (``mcap_protobuf.writer.Writer`` would write the
installed library versions there, so this module drives ``mcap.writer.Writer``
with ``mcap_protobuf``'s own schema registration instead), chunks are a fixed
size and compressed with zstd at its default level in one thread.

The file is written under a temporary name in the target folder and moved
into place only when complete: an existing file is never replaced unless
``overwrite`` is set (and then atomically, with ``os.replace``).
"""

from __future__ import annotations

import contextlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from foxglove_schemas_protobuf.CameraCalibration_pb2 import CameraCalibration
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.RawImage_pb2 import RawImage
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3
from google.protobuf.timestamp_pb2 import Timestamp
from mcap.well_known import MessageEncoding
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter
from mcap_protobuf.schema import register_schema
from scipy.spatial.transform import Rotation

from stslam.io import mcap_topics as mt
from stslam.errors import StslamError
from stslam.geometry import pose_matrix
from stslam.progress import progress

LIBRARY = "stslam-rgbd-mcap/1"
CHUNK_SIZE_BYTES = 4 * 1024 * 1024


def stamp_ns(t_s: float) -> int:
    """Nanoseconds of a time in seconds, rounded to the nearest integer."""
    return int(round(float(t_s) * 1e9))


def timestamp_message(t_ns: int) -> Timestamp:
    """``google.protobuf.Timestamp`` of a time in nanoseconds."""
    return Timestamp(seconds=t_ns // 1_000_000_000, nanos=t_ns % 1_000_000_000)


def rgb_image_message(rgb, t_ns: int, frame_id: str = mt.CAMERA_FRAME) -> RawImage:
    """``foxglove.RawImage`` (rgb8) of a uint8 image of shape (H, W, 3)."""
    rgb = np.ascontiguousarray(rgb, dtype=np.uint8)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"rgb must have shape (H, W, 3), got {rgb.shape}")
    h, w = rgb.shape[:2]
    return RawImage(timestamp=timestamp_message(t_ns), frame_id=frame_id, width=w, height=h, encoding="rgb8",
                    step=3 * w, data=rgb.tobytes())


def depth_image_message(depth_m, t_ns: int, encoding: str = "32FC1", frame_id: str = mt.CAMERA_FRAME) -> RawImage:
    """``foxglove.RawImage`` of a depth image (H, W) in metres, NaN = no return.

    ``32FC1``: little-endian float32 metres, NaN kept. ``16UC1``: little-endian
    uint16 millimetres, rounded, 0 for no return, clipped at 65.535 m.
    """
    depth = np.asarray(depth_m, dtype=np.float32)
    if depth.ndim != 2:
        raise ValueError(f"depth must have shape (H, W), got {depth.shape}")
    h, w = depth.shape
    if encoding == "32FC1":
        data, step = depth.astype("<f4").tobytes(), 4 * w
    elif encoding == "16UC1":
        mm = np.where(np.isfinite(depth), np.rint(depth * 1000.0), 0.0)
        data, step = np.clip(mm, 0, 65535).astype("<u2").tobytes(), 2 * w
    else:
        raise ValueError(f"depth encoding must be one of {', '.join(mt.DEPTH_WRITE_ENCODINGS)}, got {encoding!r}")
    return RawImage(timestamp=timestamp_message(t_ns), frame_id=frame_id, width=w, height=h, encoding=encoding,
                    step=step, data=data)


def calibration_message(K, width: int, height: int, t_ns: int, frame_id: str = mt.CAMERA_FRAME,
                        D=None) -> CameraCalibration:
    """``foxglove.CameraCalibration``: K, P = [K | 0]; by default a rectified camera (no distortion), else the
    distortion coefficients ``D`` in OpenCV's order (5: ``plumb_bob``, 8: ``rational_polynomial``)."""
    K = np.asarray(K, dtype=float)
    P = np.hstack([K, np.zeros((3, 1))])
    D = np.zeros(5) if D is None or len(D) == 0 else np.asarray(D, dtype=float).reshape(-1)
    model = "rational_polynomial" if D.size == 8 else "plumb_bob"
    D = D if D.size in (5, 8) else np.concatenate([D, np.zeros(5)])[:5]
    return CameraCalibration(timestamp=timestamp_message(t_ns), frame_id=frame_id, width=int(width),
                             height=int(height), distortion_model=model, D=D.tolist(), K=K.reshape(-1).tolist(),
                             R=np.eye(3).reshape(-1).tolist(), P=P.reshape(-1).tolist())


def transform_message(T_parent_child, parent: str, child: str, t_ns: int) -> FrameTransform:
    """``foxglove.FrameTransform`` parent → child of a 4 × 4 pose (X_parent = R X_child + t)."""
    T = np.asarray(T_parent_child, dtype=float)
    qx, qy, qz, qw = Rotation.from_matrix(T[:3, :3]).as_quat()
    return FrameTransform(timestamp=timestamp_message(t_ns), parent_frame_id=parent, child_frame_id=child,
                          translation=Vector3(x=T[0, 3], y=T[1, 3], z=T[2, 3]),
                          rotation=Quaternion(x=qx, y=qy, z=qz, w=qw))


def door_messages(hinge_point_world, hinge_axis_world, closed_direction_world, angle_rad: float,
                  t_ns: int) -> tuple[FrameTransform, FrameTransform]:
    """The two door ground-truth transforms (encoding in :mod:`stslam.io.mcap_topics`).

    Parameters
    ----------
    hinge_point_world : array_like, shape (3,)
        Point on the hinge axis (m).
    hinge_axis_world : array_like, shape (3,)
        Unit axis direction (z of ``door_hinge``).
    closed_direction_world : array_like, shape (3,)
        Unit vector from the hinge along the closed panel to its free edge, ⟂ axis (x of ``door_hinge``).
    angle_rad : float
        Door angle φ (0 = closed).
    """
    z = np.asarray(hinge_axis_world, dtype=float)
    x = np.asarray(closed_direction_world, dtype=float)
    R_world_hinge = np.column_stack([x, np.cross(z, x), z])
    hinge = transform_message(pose_matrix(R_world_hinge, hinge_point_world), mt.WORLD_FRAME, mt.DOOR_HINGE_FRAME, t_ns)
    half = 0.5 * float(angle_rad)
    panel = FrameTransform(timestamp=timestamp_message(t_ns), parent_frame_id=mt.DOOR_HINGE_FRAME,
                           child_frame_id=mt.DOOR_PANEL_FRAME, translation=Vector3(x=0.0, y=0.0, z=0.0),
                           rotation=Quaternion(x=0.0, y=0.0, z=np.sin(half), w=np.cos(half)))
    return hinge, panel


class ProtobufMcapWriter:
    """Protobuf messages into an open binary stream as MCAP, one channel per topic, deterministic."""

    def __init__(self, stream, chunk_size: int = CHUNK_SIZE_BYTES):
        self._writer = McapWriter(stream, chunk_size=chunk_size, compression=CompressionType.ZSTD)
        self._writer.start(profile="", library=LIBRARY)
        self._channels: dict[str, tuple[int, str]] = {}
        self._sequence: dict[str, int] = {}

    def write(self, topic: str, message, t_ns: int) -> None:
        """Append ``message`` on ``topic`` with log time = publish time = ``t_ns``."""
        name = type(message).DESCRIPTOR.full_name
        if topic not in self._channels:
            schema_id = register_schema(self._writer, type(message))
            channel_id = self._writer.register_channel(topic=topic, message_encoding=MessageEncoding.Protobuf,
                                                       schema_id=schema_id)
            self._channels[topic] = (channel_id, name)
            self._sequence[topic] = 0
        channel_id, expected = self._channels[topic]
        if name != expected:
            raise ValueError(f"topic {topic} carries {expected}, not {name}")
        self._writer.add_message(channel_id=channel_id, log_time=t_ns, publish_time=t_ns,
                                 data=message.SerializeToString(deterministic=True),
                                 sequence=self._sequence[topic])
        self._sequence[topic] += 1

    def write_json(self, topic: str, value, t_ns: int, schema: dict) -> None:
        """Append ``value`` as a JSON message on ``topic`` (channel of JSON Schema ``schema``; sorted keys)."""
        if topic not in self._channels:
            schema_id = self._writer.register_schema(name=schema.get("title", topic), encoding="jsonschema",
                                                     data=json.dumps(schema, sort_keys=True).encode())
            channel_id = self._writer.register_channel(topic=topic, message_encoding=MessageEncoding.JSON,
                                                       schema_id=schema_id)
            self._channels[topic] = (channel_id, "json")
            self._sequence[topic] = 0
        channel_id, expected = self._channels[topic]
        if expected != "json":
            raise ValueError(f"topic {topic} carries {expected}, not JSON")
        self._writer.add_message(channel_id=channel_id, log_time=t_ns, publish_time=t_ns,
                                 data=json.dumps(value, sort_keys=True, allow_nan=False).encode(),
                                 sequence=self._sequence[topic])
        self._sequence[topic] += 1

    def add_metadata(self, name: str, values: dict[str, str]) -> None:
        self._writer.add_metadata(name, dict(sorted(values.items())))

    def finish(self) -> None:
        self._writer.finish()


@contextlib.contextmanager
def atomic_output(path, overwrite: bool = False):
    """Open a temporary file beside ``path`` for writing; move it to ``path`` only on success.

    Without ``overwrite`` an existing ``path`` is an error, checked before and again at the end
    (``os.link`` refuses to replace); with it the file is swapped in with ``os.replace``.
    """
    path = Path(path)
    if path.exists() and not overwrite:
        raise StslamError(f"{path}: already exists; pass overwrite=true to replace it")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        with open(tmp, "wb") as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        if overwrite:
            os.replace(tmp, path)
        else:
            try:
                os.link(tmp, path)
            except FileExistsError:
                raise StslamError(f"{path}: appeared while writing; pass overwrite=true to replace it") from None
    finally:
        tmp.unlink(missing_ok=True)


@dataclass(frozen=True)
class WriteSummary:
    """What :func:`write_fridge_mcap` wrote: path, frame count and file size (bytes)."""

    path: Path
    n_frames: int
    size_bytes: int


def write_fridge_mcap(path, sequence, *, depth_encoding: str = "32FC1", overwrite: bool = False,
                      show_progress: bool = False, metadata: dict | None = None,
                      topics: mt.RGBDTopics = mt.DEFAULT_TOPICS, chunk_size: int = CHUNK_SIZE_BYTES) -> WriteSummary:
    """Render every frame of ``sequence`` (a :class:`stslam.rgbd.sequence.FridgeSequence`) into one MCAP.

    Per frame k at t_k: calibration, RGB, depth, ground-truth base pose, odometry pose and the two
    door transforms; the camera mount once, at the first frame (SPEC 9). ``chunk_size`` (bytes, before
    compression) is where a chunk is closed.
    """
    if depth_encoding not in mt.DEPTH_WRITE_ENCODINGS:
        raise StslamError(f"depth_encoding: expected one of {', '.join(mt.DEPTH_WRITE_ENCODINGS)}, "
                          f"got {depth_encoding!r}")
    room = sequence.room
    c = sequence.config
    with atomic_output(path, overwrite) as handle:
        writer = ProtobufMcapWriter(handle, chunk_size)
        for frame in progress(sequence.frames(), "fridge frames", total=len(sequence), enabled=show_progress):
            t_ns = stamp_ns(frame.t_s)
            if frame.index == 0:
                writer.write(topics.camera_mount, transform_message(sequence.T_base_camera, mt.BASE_FRAME,
                                                                    mt.CAMERA_FRAME, t_ns), t_ns)
            writer.write(topics.calibration, calibration_message(sequence.K, c.width, c.height, t_ns), t_ns)
            writer.write(topics.rgb, rgb_image_message(frame.rgb, t_ns), t_ns)
            writer.write(topics.depth, depth_image_message(frame.depth_m, t_ns, depth_encoding), t_ns)
            writer.write(topics.ground_truth_base,
                         transform_message(frame.T_world_base, mt.WORLD_FRAME, mt.BASE_FRAME, t_ns), t_ns)
            writer.write(topics.odometry,
                         transform_message(frame.T_world_base_odom, mt.WORLD_FRAME, mt.ODOM_BASE_FRAME, t_ns), t_ns)
            for message in door_messages(room.hinge_point_world, room.hinge_axis_world,
                                         room.door_closed_direction_world, frame.door_angle_rad, t_ns):
                writer.write(topics.door, message, t_ns)
        writer.add_metadata(mt.METADATA_NAME, {k: str(v) for k, v in (metadata or {}).items()})
        writer.finish()
    return WriteSummary(path=Path(path), n_frames=len(sequence), size_bytes=Path(path).stat().st_size)
