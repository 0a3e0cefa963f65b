"""Feature tracks of a whole RGB-D recording, with the poses the later stages need (SPEC 8.5, 9).

:func:`collect_tracks` streams the frames of an RGB-D MCAP
(:func:`stslam.io.mcap_read.read_rgbd_frames`) through the front end
(:class:`stslam.rgbd.frontend.FeatureTracker`) and keeps, per frame, only
the tracks' 3D observations (camera frame) with the robot poses, so that a
300-frame 640 × 480 recording never sits in memory. One frame's colour image
is kept for the figure.

The fridge experiment needs, beyond the three camera topics, the odometry
pose and the camera mount in every frame: a recording without them ends with
one :class:`~stslam.errors.InputFileError` naming the missing topic. The
ground-truth robot pose and the door's ground truth are optional (a user's
own recording, SPEC 15), but all or nothing: a recording that has them in
some frames must have them in every frame. Without them the true poses, hinge
and door angles are NaN and ``has_ground_truth`` / ``has_door_truth`` say so.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from stslam.errors import InputFileError
from stslam.rgbd.frontend import FeatureTracker, FrameObservations, TrackerSettings
from stslam.geometry import planar_pose_from_matrix, transform_points
from stslam.io.mcap_read import RGBDMcapReader
from stslam.io.mcap_topics import DEFAULT_TOPICS, RGBDTopics
from stslam.progress import progress
from stslam.robot.sensor import world_from_robot


@dataclass
class SequenceTracks:
    """Tracks and poses of one recording.

    Attributes
    ----------
    path : str
    times_s : numpy.ndarray, shape (n,)
    K : numpy.ndarray, shape (3, 3)
        Intrinsics of the first frame (pixels).
    image_size : tuple[int, int]
        (width, height) pixels.
    T_base_camera : numpy.ndarray, shape (4, 4)
        Camera mount: X_base = R X_camera + t.
    poses_gt_xytheta, poses_odom_xytheta : numpy.ndarray, shape (n, 3)
        True and odometry robot poses (m, m, rad), world frame.
    hinge_point_world, hinge_axis_world : numpy.ndarray, shape (3,)
        Door ground truth: a point on the hinge axis (m) and its unit direction.
    door_angles_rad : numpy.ndarray, shape (n,)
    frames : list[FrameObservations]
        The front end's output per frame (camera frame).
    snapshot_index : int
    snapshot_rgb : numpy.ndarray, shape (H, W, 3), uint8
        The colour image of frame ``snapshot_index``.
    frontend_seconds : float
        Time spent in the front end alone (s, wall clock).
    n_started : int
        Tracks started.
    has_ground_truth, has_door_truth : bool
        Whether the recording holds the true robot poses and the door's ground truth (else NaN above).
    topics : RGBDTopics
        The recording's topic names (to read its images again, e.g. for a scene).
    """

    path: str
    times_s: np.ndarray
    K: np.ndarray
    image_size: tuple
    T_base_camera: np.ndarray
    poses_gt_xytheta: np.ndarray
    poses_odom_xytheta: np.ndarray
    hinge_point_world: np.ndarray
    hinge_axis_world: np.ndarray
    door_angles_rad: np.ndarray
    frames: list
    snapshot_index: int
    snapshot_rgb: np.ndarray
    frontend_seconds: float
    n_started: int
    has_ground_truth: bool = True
    has_door_truth: bool = True
    topics: RGBDTopics = DEFAULT_TOPICS
    _by_track: dict = field(default_factory=dict, repr=False)

    @property
    def n_frames(self) -> int:
        return len(self.frames)

    @property
    def dts(self) -> np.ndarray:
        """Time steps (n − 1,) s between consecutive frames."""
        return np.diff(self.times_s)

    def observations_robot(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Frame ``k``'s observations in the robot (base) frame: ids (m,), z (m, 3) m, R (m, 3, 3) m².

        z = R_bc X_c + t_bc, which is SPEC 5.2's z = R(θ)ᵀ(m − [x, y, 0]ᵀ) of
        the world point m; R = R_bc Σ_c R_bcᵀ.
        """
        f: FrameObservations = self.frames[k]
        R_bc = self.T_base_camera[:3, :3]
        z = transform_points(self.T_base_camera, f.points_camera)
        covs = R_bc @ f.covs_camera @ R_bc.T
        return f.track_ids, z, covs

    def _index(self) -> dict:
        if not self._by_track:
            rows: dict = {}
            for k, f in enumerate(self.frames):
                for j, i in enumerate(f.track_ids.tolist()):
                    rows.setdefault(i, []).append((k, j))
            self._by_track = rows
        return self._by_track

    def track_lengths(self) -> dict:
        """Track id → number of 3D observations."""
        return {i: len(v) for i, v in self._index().items()}

    def track_robot(self, track_id: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """One track in the robot frame: frame indices (m,), z (m, 3) m, R (m, 3, 3) m²."""
        rows = self._index()[track_id]
        ks = np.array([k for k, _ in rows])
        z = np.empty((ks.size, 3))
        covs = np.empty((ks.size, 3, 3))
        for r, (k, j) in enumerate(rows):
            _, zk, ck = self.observations_robot(k)
            z[r], covs[r] = zk[j], ck[j]
        return ks, z, covs

    def track_pixels(self, track_id: int) -> tuple[np.ndarray, np.ndarray]:
        """Frame indices (m,) and pixels (m, 2) of one track's 3D observations."""
        rows = self._index()[track_id]
        return (np.array([k for k, _ in rows]),
                np.array([self.frames[k].pixels_uv[j] for k, j in rows]).reshape(-1, 2))


def world_points(poses_xytheta, frame_indices, z_robot) -> np.ndarray:
    """World points (m, 3) of robot-frame observations z (m, 3) at the poses of their frames.

    m = R(θ) z + [x, y, 0]ᵀ, the inverse of SPEC 5.2 (:func:`stslam.robot.sensor.world_from_robot`).
    """
    return world_from_robot(np.asarray(poses_xytheta, dtype=float)[np.asarray(frame_indices)], z_robot)


def collect_tracks(path, settings: TrackerSettings, snapshot_fraction: float = 0.35,
                   show_progress: bool = False, max_frames: int | None = None,
                   topics: RGBDTopics = DEFAULT_TOPICS) -> SequenceTracks:
    """Run the front end over the recording at ``path`` and gather tracks and poses.

    ``snapshot_fraction`` picks the frame kept for the figure (0 = first, 1 = last);
    ``max_frames`` stops early (None: all frames); ``topics``: the recording's topic names. Raises InputFileError for a
    damaged file, a missing odometry or mount topic, or ground truth in some frames only.
    """
    reader = RGBDMcapReader(path, topics)
    n_expected = reader.n_rgb_messages if max_frames is None else min(max_frames, reader.n_rgb_messages)
    snapshot_index = int(round(snapshot_fraction * max(n_expected - 1, 0)))
    tracker = FeatureTracker(settings)
    times, gt, odom, angles, frames = [], [], [], [], []
    first = None
    snapshot = None
    seconds = 0.0
    for k, frame in enumerate(progress(iter(reader), "front end", total=n_expected, enabled=show_progress)):
        if max_frames is not None and k >= max_frames:
            break
        if first is None:
            first = frame
        # (value, what, topic, required, optional): optional truth is needed once the first frame had it.
        needs = ((frame.T_world_base_odom, "odometry", topics.odometry, True, False),
                 (frame.T_base_camera, "the camera mount", topics.camera_mount, True, False),
                 (frame.T_world_base, "the ground-truth robot pose", topics.ground_truth_base,
                  first.T_world_base is not None, True),
                 (frame.door, "the door's ground truth", topics.door, first.door is not None, True))
        for value, what, topic, needed, optional in needs:
            if value is None and needed:
                raise InputFileError(reader.path, f"topic {topic}: no message at or near t = {frame.t_s:.3f} s; "
                                                  f"the fridge experiment needs {what} in every frame"
                                                  f"{' or in none' if optional else ''}")
        started = time.perf_counter()
        frames.append(tracker.step(frame.rgb, frame.depth_m, frame.K))
        seconds += time.perf_counter() - started
        times.append(frame.t_s)
        gt.append(planar_pose_from_matrix(frame.T_world_base) if frame.T_world_base is not None
                  else np.full(3, np.nan))
        odom.append(planar_pose_from_matrix(frame.T_world_base_odom))
        angles.append(frame.door.angle_rad if frame.door is not None else np.nan)
        if k == snapshot_index or snapshot is None:
            snapshot = (k, frame.rgb.copy())
    if len(frames) < 2:
        raise InputFileError(reader.path, f"{len(frames)} frame(s) read; the fridge experiment needs at least 2")
    return SequenceTracks(
        path=reader.path, times_s=np.array(times), K=first.K.copy(),
        image_size=(first.rgb.shape[1], first.rgb.shape[0]), T_base_camera=first.T_base_camera.copy(),
        poses_gt_xytheta=np.array(gt), poses_odom_xytheta=np.array(odom),
        hinge_point_world=first.door.hinge_point_world.copy() if first.door is not None else np.full(3, np.nan),
        hinge_axis_world=first.door.hinge_axis_world.copy() if first.door is not None else np.full(3, np.nan),
        door_angles_rad=np.array(angles), frames=frames, snapshot_index=snapshot[0], snapshot_rgb=snapshot[1],
        frontend_seconds=seconds, n_started=tracker.n_started, has_ground_truth=first.T_world_base is not None,
        has_door_truth=first.door is not None, topics=topics)
