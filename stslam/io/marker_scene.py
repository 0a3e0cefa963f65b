"""A marker video and its fitted joint as a Foxglove scene: ``scene.mcap`` of ``+exp=marker_video`` (SPEC 17).

Topics (Foxglove protobuf schemas; time of frame k = k / fps):

=========================  =============================  ================================================
topic                      schema                         content
=========================  =============================  ================================================
``/camera/image``          ``foxglove.CompressedImage``   the video frame as recorded (JPEG)
``/camera/calibration``    ``foxglove.CameraCalibration`` K and the lens distortion, once
``/camera/annotations``    ``foxglove.ImageAnnotations``  the marker's detected outline (a closed line in
                                                          the model's colour), the fitted axis (a line
                                                          through the lens distortion) and a text with
                                                          the model and q at that frame
``/marker``                ``foxglove.SceneUpdate``       per frame, in the reporting frame: the marker as a
                                                          sphere at its centre, coloured by the model
                                                          (``landmark/<id>``), the hinge axis (a line) or
                                                          the slide direction (an arrow) (``joint/<id>``),
                                                          and the track so far (``track``, a line strip)
=========================  =============================  ================================================

Deterministic: the same frames and fit give the same bytes.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.Point2_pb2 import Point2
from foxglove_schemas_protobuf.PointsAnnotation_pb2 import PointsAnnotation
from foxglove_schemas_protobuf.Pose_pb2 import Pose
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from foxglove_schemas_protobuf.SceneEntity_pb2 import SceneEntity
from foxglove_schemas_protobuf.TextAnnotation_pb2 import TextAnnotation

from stslam.io import mcap_topics as mt
from stslam.io.mcap_write import ProtobufMcapWriter, calibration_message, stamp_ns, timestamp_message
from stslam.io.scene_mcap import MODEL_COLOURS, SceneFrame, colour_message, landmark_update, point3

IMAGE, CALIBRATION, ANNOTATIONS, MARKER = "/camera/image", "/camera/calibration", "/camera/annotations", "/marker"
AXIS_COLOUR = (1.0, 0.85, 0.1, 1.0)
TEXT_COLOUR, TEXT_BACKGROUND = (1.0, 1.0, 1.0, 1.0), (0.0, 0.0, 0.0, 0.6)


@dataclass(frozen=True)
class MarkerJoint:
    """The fitted joint as :func:`~stslam.io.scene_mcap.landmark_update` draws it: the marker id, the model,
    a point (3,) m and a direction (3,) in the reporting frame."""

    landmark_id: int
    model: str
    point: np.ndarray
    direction: np.ndarray
    radius_m: float = 0.0


@dataclass(frozen=True)
class MarkerSceneFrame:
    """One video frame: its JPEG bytes, the marker's outline (4, 2) px or None, the fitted axis as a pixel
    polyline (m, 2) or None, the label text, and the marker's centre (3,) m in the reporting frame or None."""

    jpeg: bytes
    outline_px: np.ndarray | None
    axis_px: np.ndarray | None
    label: str
    centre: np.ndarray | None


def _line(points_px, rgba, closed: bool, stamp, thickness: float = 3.0) -> PointsAnnotation:
    kind = PointsAnnotation.LINE_LOOP if closed else PointsAnnotation.LINE_STRIP
    return PointsAnnotation(timestamp=stamp, type=kind, thickness=thickness, outline_color=colour_message(rgba),
                            points=[Point2(x=float(u), y=float(v)) for u, v in np.asarray(points_px, float)])


def annotations(frame: MarkerSceneFrame, model: str, t_ns: int) -> ImageAnnotations:
    """``/camera/annotations`` of one frame (module docstring)."""
    stamp = timestamp_message(t_ns)
    out = ImageAnnotations()
    if frame.outline_px is not None:
        out.points.append(_line(frame.outline_px, MODEL_COLOURS[model], True, stamp))
    if frame.axis_px is not None and len(frame.axis_px) >= 2:
        out.points.append(_line(frame.axis_px, AXIS_COLOUR, False, stamp, thickness=4.0))
    out.texts.append(TextAnnotation(timestamp=stamp, position=Point2(x=8.0, y=20.0), text=frame.label,
                                    font_size=16.0, text_color=colour_message(TEXT_COLOUR),
                                    background_color=colour_message(TEXT_BACKGROUND)))
    return out


def marker_scene_bytes(frames, fps: float, K, D, size: tuple[int, int], model: str, joint: MarkerJoint | None,
                       frame_id: str = mt.CAMERA_FRAME) -> bytes:
    """The bytes of ``scene.mcap`` (module docstring) of :class:`MarkerSceneFrame` s at ``fps`` Hz."""
    stream = io.BytesIO()
    writer = ProtobufMcapWriter(stream, chunk_size=1024 * 1024)
    writer.write(CALIBRATION, calibration_message(K, *size, 0, D=D), 0)
    track: list = []
    marker_id = 0 if joint is None else joint.landmark_id
    for k, frame in enumerate(frames):
        t_ns = stamp_ns(k / fps)
        stamp = timestamp_message(t_ns)
        writer.write(IMAGE, CompressedImage(timestamp=stamp, frame_id=mt.CAMERA_FRAME, data=frame.jpeg,
                                            format="jpeg"), t_ns)
        writer.write(ANNOTATIONS, annotations(frame, model, t_ns), t_ns)
        if frame.centre is not None:
            track.append(np.asarray(frame.centre, dtype=float))
        positions = np.array(track[-1:]).reshape(-1, 3) if frame.centre is not None else np.zeros((0, 3))
        scene = SceneFrame(t_s=k / fps, ids=np.full(positions.shape[0], marker_id), positions=positions,
                           models=(model,) * positions.shape[0], joints=() if joint is None else (joint,))
        update = landmark_update(scene, t_ns, frame_id)
        if len(track) >= 2:
            update.entities.append(SceneEntity(timestamp=stamp, frame_id=frame_id, id="track", lines=[
                LinePrimitive(type=LinePrimitive.LINE_STRIP, pose=Pose(orientation=Quaternion(w=1.0)),
                              thickness=0.01, color=colour_message(MODEL_COLOURS[model]),
                              points=[point3(p) for p in track])]))
        writer.write(MARKER, update, t_ns)
    writer.finish()
    return stream.getvalue()
