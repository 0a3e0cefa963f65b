"""What A-SLAM believed in every frame, as plain arrays for a scene (SPEC 15); no I/O here.

:class:`SceneRecorder` is an ``observer(k, state)`` for
:func:`stslam.slam.loop.run_slam` (via :func:`stslam.slam.filters.run_filter`):
after each frame it copies the robot pose and, per landmark in the state, its
world position and, for a landmark on an articulated block, the joint (axis
point and direction with the radius for revolute, a point on the line and
the slide direction for prismatic). It reads the state and never changes it.

:func:`landmark_frames` combines that with A-SLAM's landmark reports
(:class:`stslam.slam.a_slam.LandmarkReport`) into the model each landmark
held in each frame: an articulated block's model, else the latest decision
made up to that frame (a chosen model awaiting conversion counts as chosen,
as in :attr:`stslam.slam.landmark_policy.LandmarkMark.model`), else
``undecided``. A restart after a static decision is not among the reports'
decisions, so such a landmark stays ``static`` in the scene.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stslam.slam.blocks import ArticulatedBlock

MODELS = ("undecided", "static", "prismatic", "revolute")


@dataclass(frozen=True)
class Joint:
    """An articulated landmark's joint in the world (m): revolute axis or prismatic line."""

    landmark_id: int
    model: str
    point: np.ndarray
    direction: np.ndarray
    radius_m: float = float("nan")


@dataclass(frozen=True)
class LandmarkFrame:
    """The landmarks of one frame: ids (m,), world positions (m, 3) m, models (m,), joints, and μ updates.

    ``mu`` maps a landmark id to {model name: probability} for landmarks whose selector was fed in
    this frame.
    """

    k: int
    ids: np.ndarray
    positions: np.ndarray
    models: tuple
    joints: tuple
    mu: dict


def _joint(landmark_id: int, block) -> tuple[str | None, Joint | None]:
    if not isinstance(block, ArticulatedBlock):
        return None, None
    name, s = block.model.name, block.structure
    if name == "revolute":
        return name, Joint(landmark_id, name, np.array(s.axis_point, float), np.array(s.axis_direction, float),
                           float(s.radius))
    if name == "prismatic":
        return name, Joint(landmark_id, name, np.array(s.p0, float), np.array(s.direction, float))
    return name, None


class SceneRecorder:
    """``observer(k, state)`` keeping, per frame, the pose and every landmark's position, block model and joint."""

    def __init__(self):
        self.poses: list[np.ndarray] = []
        self.records: list[dict] = []

    def __call__(self, k: int, state) -> None:
        record = {}
        for i in state.landmark_ids:
            position = state.landmark_point(i)
            model, joint = _joint(i, state.block(i))
            record[i] = (np.array(position, dtype=float), model, joint)
        self.poses.append(np.array(state.pose, dtype=float))
        self.records.append(record)


def _model_at(report, k: int, block_model: str | None) -> str:
    if block_model in ("prismatic", "revolute"):
        return block_model
    chosen = [model for frame, _, model in (report.decisions if report is not None else ()) if frame <= k]
    return chosen[-1] if chosen else "undecided"


def _mu_by_frame(reports: dict) -> dict:
    out: dict = {}
    for i, report in reports.items():
        for frame, row in zip(report.mu_frames.tolist(), report.mu, strict=True):
            if np.all(np.isfinite(row)):
                out.setdefault(int(frame), {})[int(i)] = dict(zip(report.model_names, map(float, row), strict=True))
    return out


def landmark_frames(recorder: SceneRecorder, reports: dict) -> list[LandmarkFrame]:
    """Per frame, the landmarks with the model each held then (see the module docstring)."""
    mu = _mu_by_frame(reports)
    frames = []
    for k, record in enumerate(recorder.records):
        ids = sorted(record)
        models = tuple(_model_at(reports.get(i), k, record[i][1]) for i in ids)
        positions = np.array([record[i][0] for i in ids], dtype=float).reshape(-1, 3)
        joints = tuple(record[i][2] for i in ids if record[i][2] is not None)
        frames.append(LandmarkFrame(k, np.array(ids, dtype=int), positions, models, joints, mu.get(k, {})))
    return frames
