"""The small topics of an RGB-D MCAP (calibration, poses, camera mount, door), gathered as they are read (SPEC 9).

:class:`~stslam.io.mcap_read.RGBDMcapReader` reads them in the same pass as the images: a frame
waits until every small topic has reached past its time (:meth:`SideTopics.settled`), so what
it is given is what a first pass over the whole file would have given it, without reading
(and decompressing) the file twice. A topic has reached past a time ``t`` once each of its
child frames has a stamp after ``t`` (stamps increase per child, which is checked), or once
all its messages are in (their number is in the file's summary statistics).
"""

from __future__ import annotations

import bisect

import numpy as np

from stslam.errors import InputFileError
from stslam.io import mcap_topics as mt
from stslam.io.mcap_errors import reading
from stslam.io.pose_track import PoseTrack, checked_parts


def stamp_s(decoded, log_time_ns: int) -> float:
    """A message's header stamp (s), else its log time."""
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
    """(stamp s, parent, child, unit quaternion, translation) of each pose in a message (:func:`pose_parts`)."""
    for stamped, parent, child, q, p in pose_parts(schema, topic, decoded):
        yield (stamp_s(stamped, log_time_ns), parent, child,
               *checked_parts(q, p, path, f"topic {topic}: transform {parent} → {child}"))


class Track(PoseTrack):
    """Time-stamped 4 × 4 transforms of one child frame, interpolated on demand."""

    def __init__(self, parent: str):
        super().__init__()
        self.parent = parent

    def latest(self, t: float) -> np.ndarray | None:
        """The last pose at or before ``t``, else the first (for fixed transforms)."""
        if not self.times:
            return None
        return self._made()[max(0, bisect.bisect_right(self.times, t) - 1)]


def check_increasing(path, topic: str, key, t: float, last: dict) -> None:
    previous = last.get(key)
    if previous is not None and t <= previous:
        raise InputFileError(path, f"topic {topic}: time stamps must increase, got {t:.9f} s after {previous:.9f} s")
    last[key] = t


class SideTopics:
    """Calibrations and pose tracks of the small topics present in a file, filled message by message.

    Parameters
    ----------
    path : str
    topics : stslam.io.mcap_topics.RGBDTopics
    schemas : dict[str, str]
        Schema name of each topic present.
    counts : dict[str, int] or None
        Messages of each small topic in the file (its summary statistics); None when unknown, and
        then nothing is settled before :meth:`finish`.
    """

    def __init__(self, path: str, topics: mt.RGBDTopics, schemas: dict, counts: dict | None):
        t = topics
        self.path, self.topics, self.schemas = path, topics, schemas
        self.names = [x for x in (t.calibration, t.ground_truth_base, t.ground_truth_camera, t.odometry,
                                  t.camera_mount, t.door) if x in schemas]
        self.calibrations: list[tuple[float, np.ndarray, int, int, str, np.ndarray]] = []
        self.calibration_times: list[float] = []  # increasing (checked), for bisect
        self.tracks: dict[str, dict[str, Track]] = {topic: {} for topic in self.names}
        self.counts, self.seen = counts, dict.fromkeys(self.names, 0)
        self.complete = False
        self._last: dict = {}
        if counts is not None and counts.get(t.calibration, 0) == 0:
            raise InputFileError(path, f"topic {t.calibration}: no messages")

    def add(self, topic: str, decoded, log_time_ns: int) -> None:
        """One message of a small topic, in log-time order."""
        t = self.topics
        self.seen[topic] += 1
        with reading(self.path, topic):
            if topic == t.calibration:
                stamp = stamp_s(decoded, log_time_ns)
                check_increasing(self.path, topic, topic, stamp, self._last)
                K = np.asarray(decoded.K, dtype=float)
                if K.size != 9 or K[0] == 0 or not np.all(np.isfinite(K)):
                    raise InputFileError(self.path, f"topic {topic}: K must hold 9 finite numbers with "
                                                    f"fx ≠ 0, got {K.tolist()}")
                self.calibrations.append((stamp, K.reshape(3, 3), decoded.width, decoded.height,
                                          decoded.distortion_model, np.asarray(decoded.D, dtype=float)))
                self.calibration_times.append(stamp)
                return
            for stamp, parent, child, q, p in _poses(self.path, topic, self.schemas[topic], decoded, log_time_ns):
                check_increasing(self.path, topic, (topic, child), stamp, self._last)
                tracks = self.tracks[topic]
                if child not in tracks and len(tracks) == self._children(topic):
                    raise self._children_error(topic, [*tracks, child])
                tracks.setdefault(child, Track(parent)).add(stamp, q, p)

    def _children(self, topic: str) -> int:
        return 2 if topic == self.topics.door else 1

    def _children_error(self, topic: str, children) -> InputFileError:
        return InputFileError(self.path, f"topic {topic}: expected {self._children(topic)} child frame(s), got "
                                         f"{', '.join(sorted(children))}")

    def settled(self, t: float) -> bool:
        """Whether every small topic has reached past ``t``: nothing still to come can change what it gives at t."""
        if self.complete:
            return True
        if self.counts is None:
            return False
        for topic in self.names:
            if self.seen[topic] >= self.counts[topic]:
                continue  # all its messages are in
            if topic == self.topics.calibration:
                if not self.calibration_times or self.calibration_times[-1] <= t:
                    return False
                continue
            tracks = self.tracks[topic]
            if len(tracks) < self._children(topic) or any(track.times[-1] <= t for track in tracks.values()):
                return False
        return True

    def finish(self) -> None:
        """Every message is in: the checks that need them all."""
        if not self.calibrations:
            raise InputFileError(self.path, f"topic {self.topics.calibration}: no messages")
        for topic, tracks in self.tracks.items():
            if tracks and len(tracks) != self._children(topic):
                raise self._children_error(topic, tracks)
        self.complete = True

    def door_tracks(self) -> tuple[Track, Track] | None:
        """(hinge, panel) tracks of the door topic: the panel's parent is the hinge frame; None without a door."""
        tracks = self.tracks.get(self.topics.door)
        if not tracks or len(tracks) < 2:
            return None
        (a, track_a), (b, track_b) = sorted(tracks.items())
        if track_b.parent == a:
            return track_a, track_b
        if track_a.parent == b:
            return track_b, track_a
        raise InputFileError(self.path, f"topic {self.topics.door}: expected a hinge transform and a panel "
                                        f"transform whose parent is the hinge frame, got {a} and {b}")

    def calibration(self, t: float) -> tuple:
        """The calibration at or before ``t``, else the first."""
        return self.calibrations[max(0, bisect.bisect_right(self.calibration_times, t) - 1)]

    def pose(self, topic: str, t: float, max_offset: float) -> np.ndarray | None:
        """The pose of a one-child topic at ``t`` (:meth:`PoseTrack.at`), None when absent."""
        tracks = self.tracks.get(topic)
        if not tracks:
            return None
        return next(iter(tracks.values())).at(t, max_offset)

    def latest(self, topic: str, t: float) -> np.ndarray | None:
        """The latest pose of a one-child topic at or before ``t`` (:meth:`Track.latest`), None when absent."""
        tracks = self.tracks.get(topic)
        return next(iter(tracks.values())).latest(t) if tracks else None
