"""A SLAM run as a Foxglove scene: one MCAP with Foxglove protobuf schemas (SPEC 15).

Topics of ``scene.mcap`` (frames ``world``, ``base_link``, ``camera_optical`` as in
:mod:`stslam.io.mcap_topics`; time of frame k = the run's time stamp):

=========================  ===========================  ==================================================
topic                      schema                       content
=========================  ===========================  ==================================================
``/trajectory/<name>``     ``foxglove.PosesInFrame``    the whole path of a method (``groundtruth`` = true),
                                                        once, at the first frame
``/pose/<name>``           ``foxglove.PoseInFrame``     its pose in every frame
``/tf``                    ``foxglove.FrameTransform``  world → base_link (the estimate's pose) per frame;
                                                        base_link → camera_optical once (RGB-D runs)
``/landmarks``             ``foxglove.SceneUpdate``     per frame: all entities replaced; ``landmark/<id>``
                                                        a sphere at the estimated position, coloured by its
                                                        current model (:data:`MODEL_COLOURS`);
                                                        ``joint/<id>`` the revolute axis (a line) or the
                                                        prismatic slide direction (an arrow)
``/landmarks/true``        ``foxglove.SceneUpdate``     true landmark positions (simulated runs)
``/mu``                    JSON (``stslam.Mu``)         per frame, the μ of each landmark whose selector was
                                                        fed: ``{"frame": k, "landmarks": [{"id": i,
                                                        "static": μ, "prismatic": μ, "revolute": μ}]}``;
                                                        plot e.g. ``/mu.landmarks[:]{id==12}.revolute``
``/camera/image``          ``foxglove.CompressedImage``  colour image (JPEG), RGB-D runs
``/camera/calibration``    ``foxglove.CameraCalibration``  its intrinsics
``/camera/corners``        ``foxglove.ImageAnnotations``  tracked corners, one points annotation per model
=========================  ===========================  ==================================================

Deterministic: the same scene gives the same bytes (fixed library string, times
from the run, no wall clock).
"""

from __future__ import annotations

import io
from collections.abc import Iterable
from dataclasses import dataclass, field

import cv2
import numpy as np
from foxglove_schemas_protobuf.ArrowPrimitive_pb2 import ArrowPrimitive
from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Point2_pb2 import Point2
from foxglove_schemas_protobuf.Point3_pb2 import Point3
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.SceneEntityDeletion_pb2 import SceneEntityDeletion
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from foxglove_schemas_protobuf.SpherePrimitive_pb2 import SpherePrimitive
from foxglove_schemas_protobuf.Vector3_pb2 import Vector3

from stslam.io import mcap_topics as mt
from stslam.io.mcap_write import (ProtobufMcapWriter, calibration_message, stamp_ns, timestamp_message,
                                  transform_message)

# SPEC 15: static red, prismatic green, revolute blue, undecided grey (RGBA, 0–1).
MODEL_COLOURS = {"static": (0.85, 0.15, 0.15, 1.0), "prismatic": (0.1, 0.7, 0.2, 1.0),
                 "revolute": (0.15, 0.35, 0.9, 1.0), "undecided": (0.6, 0.6, 0.6, 1.0)}
TRUE_COLOUR = (1.0, 1.0, 1.0, 0.6)
TRAJECTORY_PREFIX, POSE_PREFIX = "/trajectory/", "/pose/"
LANDMARKS, TRUE_LANDMARKS, MU, TF = "/landmarks", "/landmarks/true", "/mu", "/tf"
IMAGE, CALIBRATION, CORNERS = "/camera/image", "/camera/calibration", "/camera/corners"
SPHERE_M, AXIS_HALF_LENGTH_M, ARROW_M = 0.06, 0.6, 0.4
MU_SCHEMA = {"title": "stslam.Mu", "type": "object",
             "properties": {"frame": {"type": "integer"},
                            "landmarks": {"type": "array", "items": {"type": "object", "properties": {
                                "id": {"type": "integer"}, "static": {"type": "number"},
                                "prismatic": {"type": "number"}, "revolute": {"type": "number"}}}}}}


@dataclass(frozen=True)
class SceneFrame:
    """One frame of a scene: landmark ids (m,), world positions (m, 3) m, models (m,), joints, μ updates.

    ``joints`` hold objects with ``landmark_id``, ``model``, ``point`` (3,), ``direction`` (3,) and
    ``radius_m`` (e.g. :class:`stslam.slam.scene_record.Joint`); ``mu`` maps an id to {model: μ}.
    Optional: true positions (p, 3), the colour image (H, W, 3) uint8 with tracked corners
    (q, 2) pixels and their models (q,).
    """

    t_s: float
    ids: np.ndarray
    positions: np.ndarray
    models: tuple
    joints: tuple = ()
    mu: dict = field(default_factory=dict)
    true_positions: np.ndarray | None = None
    image_rgb: np.ndarray | None = None
    corners_uv: np.ndarray | None = None
    corner_models: tuple = ()


@dataclass
class Scene:
    """A run to draw: per-method planar paths (n, 3) (x m, y m, θ rad) at ``times_s`` (n,), frames.

    ``estimate`` names the path whose pose drives the ``world → base_link`` transform; ``K``
    (3 × 3), ``T_base_camera`` (4 × 4) and ``image_size`` (width, height) describe the camera of an
    RGB-D run. ``frames`` may be a generator (images are then never all in memory).
    """

    times_s: np.ndarray
    paths: dict
    frames: Iterable
    estimate: str = "a_slam"
    K: np.ndarray | None = None
    T_base_camera: np.ndarray | None = None
    image_size: tuple | None = None
    jpeg_quality: int = 85


def colour_message(rgba) -> Color:
    """``foxglove.Color`` of an RGBA tuple (0–1)."""
    return Color(r=rgba[0], g=rgba[1], b=rgba[2], a=rgba[3])


def _quaternion_from_yaw(theta: float) -> Quaternion:
    return Quaternion(x=0.0, y=0.0, z=float(np.sin(0.5 * theta)), w=float(np.cos(0.5 * theta)))


def _planar_pose(pose_xytheta) -> Pose:
    x, y, theta = (float(v) for v in pose_xytheta)
    return Pose(position=Vector3(x=x, y=y, z=0.0), orientation=_quaternion_from_yaw(theta))


def _planar_matrix(pose_xytheta) -> np.ndarray:
    x, y, theta = (float(v) for v in pose_xytheta)
    T = np.eye(4)
    T[:2, :2] = [[np.cos(theta), -np.sin(theta)], [np.sin(theta), np.cos(theta)]]
    T[:2, 3] = [x, y]
    return T


def _x_to(direction) -> Quaternion:
    """Rotation taking +x to ``direction`` (an arrow primitive points along its +x)."""
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    axis = np.cross([1.0, 0.0, 0.0], d)
    s, c = np.linalg.norm(axis), float(d[0])
    if s < 1e-12:
        return Quaternion(x=0.0, y=0.0, z=0.0, w=1.0) if c > 0 else Quaternion(x=0.0, y=0.0, z=1.0, w=0.0)
    half = 0.5 * np.arctan2(s, c)
    a = axis / s * np.sin(half)
    return Quaternion(x=a[0], y=a[1], z=a[2], w=float(np.cos(half)))


def point3(p) -> Point3:
    """``foxglove.Point3`` of a point (3,) m."""
    return Point3(x=float(p[0]), y=float(p[1]), z=float(p[2]))


def landmark_update(frame: SceneFrame, t_ns: int, frame_id: str = mt.WORLD_FRAME) -> SceneUpdate:
    """``/landmarks`` of one frame: delete all, then a sphere per landmark and a primitive per joint (in ``frame_id``)."""
    stamp = timestamp_message(t_ns)
    update = SceneUpdate(deletions=[SceneEntityDeletion(timestamp=stamp, type=SceneEntityDeletion.ALL)])
    size = Vector3(x=SPHERE_M, y=SPHERE_M, z=SPHERE_M)
    for i, p, model in zip(frame.ids.tolist(), frame.positions, frame.models, strict=True):
        sphere = SpherePrimitive(pose=Pose(position=Vector3(x=p[0], y=p[1], z=p[2]),
                                           orientation=Quaternion(w=1.0)), size=size,
                                 color=colour_message(MODEL_COLOURS[model]))
        update.entities.append(SceneEntity(timestamp=stamp, frame_id=frame_id, id=f"landmark/{i}",
                                           spheres=[sphere], metadata=[]))
    for joint in frame.joints:
        colour = colour_message(MODEL_COLOURS[joint.model])
        entity = SceneEntity(timestamp=stamp, frame_id=frame_id, id=f"joint/{joint.landmark_id}")
        d = np.asarray(joint.direction, dtype=float)
        p = np.asarray(joint.point, dtype=float)
        if joint.model == "revolute":
            entity.lines.append(LinePrimitive(type=LinePrimitive.LINE_STRIP, pose=Pose(orientation=Quaternion(w=1.0)),
                                              thickness=0.02, color=colour,
                                              points=[point3(p - AXIS_HALF_LENGTH_M * d),
                                                      point3(p + AXIS_HALF_LENGTH_M * d)]))
        else:
            entity.arrows.append(ArrowPrimitive(pose=Pose(position=Vector3(x=p[0], y=p[1], z=p[2]),
                                                          orientation=_x_to(d)),
                                                shaft_length=ARROW_M, shaft_diameter=0.02, head_length=0.08,
                                                head_diameter=0.05, color=colour))
        update.entities.append(entity)
    return update


def _true_update(positions, t_ns: int) -> SceneUpdate:
    stamp = timestamp_message(t_ns)
    size = Vector3(x=0.5 * SPHERE_M, y=0.5 * SPHERE_M, z=0.5 * SPHERE_M)
    spheres = [SpherePrimitive(pose=Pose(position=Vector3(x=p[0], y=p[1], z=p[2]), orientation=Quaternion(w=1.0)),
                               size=size, color=colour_message(TRUE_COLOUR)) for p in np.asarray(positions, float)]
    return SceneUpdate(entities=[SceneEntity(timestamp=stamp, frame_id=mt.WORLD_FRAME, id="true", spheres=spheres)])


def _corners(frame: SceneFrame, t_ns: int) -> ImageAnnotations:
    stamp = timestamp_message(t_ns)
    out = ImageAnnotations()
    uv = np.asarray(frame.corners_uv, dtype=float).reshape(-1, 2)
    for model, rgba in MODEL_COLOURS.items():
        chosen = [j for j, m in enumerate(frame.corner_models) if m == model]
        if chosen:
            out.points.append(PointsAnnotation(timestamp=stamp, type=PointsAnnotation.POINTS, thickness=5.0,
                                               outline_color=colour_message(rgba), fill_color=colour_message(rgba),
                                               points=[Point2(x=uv[j, 0], y=uv[j, 1]) for j in chosen]))
    return out


def _write_frame(writer, scene: Scene, k: int, frame: SceneFrame) -> None:
    t_ns = stamp_ns(frame.t_s)
    writer.write(TF, transform_message(_planar_matrix(scene.paths[scene.estimate][k]), mt.WORLD_FRAME,
                                       mt.BASE_FRAME, t_ns), t_ns)
    for name, path in scene.paths.items():
        writer.write(POSE_PREFIX + name, PoseInFrame(timestamp=timestamp_message(t_ns), frame_id=mt.WORLD_FRAME,
                                                    pose=_planar_pose(path[k])), t_ns)
    writer.write(LANDMARKS, landmark_update(frame, t_ns), t_ns)
    if frame.true_positions is not None:
        writer.write(TRUE_LANDMARKS, _true_update(frame.true_positions, t_ns), t_ns)
    rows = [{"id": int(i), **{m: float(v) for m, v in mu.items()}} for i, mu in sorted(frame.mu.items())]
    writer.write_json(MU, {"frame": k, "landmarks": rows}, t_ns, MU_SCHEMA)
    if frame.image_rgb is not None:
        ok, jpeg = cv2.imencode(".jpg", np.ascontiguousarray(frame.image_rgb[..., ::-1]),
                                [cv2.IMWRITE_JPEG_QUALITY, scene.jpeg_quality])
        if not ok:
            raise ValueError(f"frame {k}: the colour image could not be JPEG-encoded")
        writer.write(IMAGE, CompressedImage(timestamp=timestamp_message(t_ns), frame_id=mt.CAMERA_FRAME,
                                            data=jpeg.tobytes(), format="jpeg"), t_ns)
        if frame.corners_uv is not None:
            writer.write(CORNERS, _corners(frame, t_ns), t_ns)


def scene_mcap_bytes(scene: Scene) -> bytes:
    """The bytes of ``scene.mcap`` for ``scene`` (topics in the module docstring)."""
    if scene.estimate not in scene.paths:
        raise ValueError(f"estimate {scene.estimate!r} is not among the paths {sorted(scene.paths)}")
    stream = io.BytesIO()
    writer = ProtobufMcapWriter(stream, chunk_size=1024 * 1024)
    t0 = stamp_ns(scene.times_s[0])
    for name, path in scene.paths.items():
        poses = [_planar_pose(p) for p in np.asarray(path, dtype=float)]
        writer.write(TRAJECTORY_PREFIX + name, PosesInFrame(timestamp=timestamp_message(t0), frame_id=mt.WORLD_FRAME,
                                                            poses=poses), t0)
    if scene.T_base_camera is not None:
        writer.write(TF, transform_message(scene.T_base_camera, mt.BASE_FRAME, mt.CAMERA_FRAME, t0), t0)
    if scene.K is not None and scene.image_size is not None:
        writer.write(CALIBRATION, calibration_message(scene.K, *scene.image_size, t0), t0)
    for k, frame in enumerate(scene.frames):
        _write_frame(writer, scene, k, frame)
    writer.finish()
    return stream.getvalue()
