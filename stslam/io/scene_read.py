"""Read one frame of a ``scene.mcap`` (:mod:`stslam.io.scene_mcap`) back as arrays, e.g. for a figure.

Only the topics that module writes are read; the models come back from the
sphere colours (:data:`stslam.io.scene_mcap.MODEL_COLOURS`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
from foxglove_schemas_protobuf.ImageAnnotations_pb2 import ImageAnnotations
from foxglove_schemas_protobuf.PosesInFrame_pb2 import PosesInFrame
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate
from mcap.reader import make_reader

from stslam.errors import InputFileError
from stslam.io import scene_mcap as sm


@dataclass
class SceneSnapshot:
    """One frame of a scene: paths (name → (n, 2) x, y m), landmarks, joints, image and corners.

    ``positions`` (m, 3) m with ``models`` (m,); ``axes`` and ``slides``: lists of
    (model, point (3,), direction (3,)); ``image_rgb`` (H, W, 3) uint8 or None; ``corners``:
    model → (q, 2) pixels; ``model_colours``: model → RGBA (0–1) the scene draws it in.
    """

    frame: int
    n_frames: int
    paths: dict = field(default_factory=dict)
    positions: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    models: list = field(default_factory=list)
    joints: list = field(default_factory=list)
    image_rgb: np.ndarray | None = None
    corners: dict = field(default_factory=dict)
    model_colours: dict = field(default_factory=lambda: dict(sm.MODEL_COLOURS))


def _model_of(colour) -> str:
    rgba = (colour.r, colour.g, colour.b, colour.a)
    return min(sm.MODEL_COLOURS, key=lambda m: float(np.sum((np.array(sm.MODEL_COLOURS[m]) - rgba) ** 2)))


def _landmarks(snapshot: SceneSnapshot, update: SceneUpdate) -> None:
    positions, models = [], []
    for entity in update.entities:
        if entity.id.startswith("landmark/"):
            p = entity.spheres[0].pose.position
            positions.append((p.x, p.y, p.z))
            models.append(_model_of(entity.spheres[0].color))
        for line in entity.lines:
            a, b = (np.array([q.x, q.y, q.z]) for q in line.points[:2])
            snapshot.joints.append((_model_of(line.color), 0.5 * (a + b), (b - a) / np.linalg.norm(b - a)))
        for arrow in entity.arrows:
            p, q = arrow.pose.position, arrow.pose.orientation
            # The arrow's +x axis rotated by its quaternion.
            d = np.array([1 - 2 * (q.y ** 2 + q.z ** 2), 2 * (q.x * q.y + q.w * q.z), 2 * (q.x * q.z - q.w * q.y)])
            snapshot.joints.append((_model_of(arrow.color), np.array([p.x, p.y, p.z]), d))
    snapshot.positions = np.array(positions, dtype=float).reshape(-1, 3)
    snapshot.models = models


def read_scene_frame(path, frame: int | None = None) -> SceneSnapshot:
    """Frame ``frame`` (0-based; None = the last) of the scene at ``path``."""
    try:
        with open(path, "rb") as handle:
            reader = make_reader(handle)
            summary = reader.get_summary()
            counts = summary.statistics.channel_message_counts
            n = next(counts[c.id] for c in summary.channels.values() if c.topic == sm.LANDMARKS)
            k = n - 1 if frame is None else frame
            if not 0 <= k < n:
                raise InputFileError(path, f"frame {frame}: the scene has frames 0 … {n - 1}")
            snapshot = SceneSnapshot(frame=k, n_frames=n)
            seen: dict = {}
            for _, channel, message in reader.iter_messages(log_time_order=True):
                topic = channel.topic
                index = seen.get(topic, 0)
                seen[topic] = index + 1
                if topic.startswith(sm.TRAJECTORY_PREFIX):
                    poses = PosesInFrame.FromString(message.data).poses
                    snapshot.paths[topic[len(sm.TRAJECTORY_PREFIX):]] = np.array(
                        [(p.position.x, p.position.y) for p in poses], dtype=float).reshape(-1, 2)
                elif index != k:
                    continue
                elif topic == sm.LANDMARKS:
                    _landmarks(snapshot, SceneUpdate.FromString(message.data))
                elif topic == sm.IMAGE:
                    data = np.frombuffer(CompressedImage.FromString(message.data).data, dtype=np.uint8)
                    snapshot.image_rgb = cv2.imdecode(data, cv2.IMREAD_COLOR)[..., ::-1].copy()
                elif topic == sm.CORNERS:
                    for points in ImageAnnotations.FromString(message.data).points:
                        snapshot.corners[_model_of(points.outline_color)] = np.array(
                            [(q.x, q.y) for q in points.points], dtype=float).reshape(-1, 2)
    except InputFileError:
        raise
    except Exception as error:  # the mcap and protobuf libraries raise many kinds on a damaged file
        raise InputFileError(path, f"not a readable scene.mcap ({type(error).__name__}: {error})") from None
    return snapshot
