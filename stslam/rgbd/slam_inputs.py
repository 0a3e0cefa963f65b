"""SLAM inputs from RGB-D feature tracks for a planar robot (SPEC 5.2, 6, 8.5).

The filters are those of ``dynamic_slam`` (:mod:`stslam.slam`, run by
:func:`stslam.slam.filters.run_filter`): this module only turns a recording's
tracks into their :class:`~stslam.slam.inputs.SlamInputs`.

* **Observations.** The camera mount carries each camera-frame point into the
  robot frame, z = R_bc X_c + t_bc, which is exactly SPEC 5.2's
  z = R(θ)ᵀ(m − [x, y, 0]ᵀ) for the landmark's world point m; its noise
  R = R_bc Σ_c R_bcᵀ comes per observation from the depth model
  (:mod:`stslam.rgbd.frontend`).
* **Controls.** The odometry poses of consecutive frames give the control
  (v, ω) by inverting SPEC 5.1 (:func:`stslam.robot.motion.control_between`), with
  δt from the time stamps; the filters assume S(û) with the configured α.
* **Landmarks.** A track is a landmark with its id (data association by the
  tracker). To bound the state, only tracks with at least
  ``min_track_frames`` 3D observations take part, the longest
  ``max_landmarks`` of them (ties by id): the paper kept only long tracks too
  (SPEC 8.5).
"""

from __future__ import annotations

import numpy as np

from stslam.rgbd.tracks import SequenceTracks
from stslam.robot.motion import control_between, control_noise_cov
from stslam.slam.inputs import SlamInputs


def select_landmarks(tracks: SequenceTracks, min_track_frames: int, max_landmarks: int) -> list[int]:
    """Ids of the longest ``max_landmarks`` tracks with ≥ ``min_track_frames`` observations (ties by id)."""
    lengths = [(n, i) for i, n in tracks.track_lengths().items() if n >= min_track_frames]
    lengths.sort(key=lambda ni: (-ni[0], ni[1]))
    return sorted(i for _, i in lengths[:max_landmarks])


def odometry_controls(poses_odom_xytheta, times_s) -> np.ndarray:
    """Controls (n − 1, 2) (v m/s, ω rad/s) between consecutive odometry poses (SPEC 5.1 inverted)."""
    poses = np.asarray(poses_odom_xytheta, dtype=float)
    dts = np.diff(np.asarray(times_s, dtype=float))
    return np.array([control_between(poses[k], poses[k + 1], dts[k]) for k in range(dts.size)]).reshape(-1, 2)


def frame_inputs(tracks: SequenceTracks, landmark_ids) -> list:
    """Per frame (ids (m,), z (m, 3) robot frame m, R (m, 3, 3) m²) of the chosen landmarks only."""
    chosen = set(int(i) for i in landmark_ids)
    out = []
    for k in range(tracks.n_frames):
        ids, z, covs = tracks.observations_robot(k)
        keep = np.array([int(i) in chosen for i in ids], dtype=bool)
        out.append((ids[keep], z[keep], covs[keep]))
    return out


def inputs_from_tracks(tracks: SequenceTracks, landmark_ids, alpha) -> SlamInputs:
    """The filters' inputs of a recording: the chosen landmarks' observations, odometry controls with S(û).

    Starts from the true first pose (the odometry's first pose in a recording without ground truth,
    whose world frame is then the odometry frame); δt from the time stamps (s); S(û) by
    SPEC 5.1 with ``alpha`` (α1…α4) on each odometry control.
    """
    controls = odometry_controls(tracks.poses_odom_xytheta, tracks.times_s)
    frames = frame_inputs(tracks, landmark_ids)
    return SlamInputs(
        initial_pose_xytheta=np.asarray(tracks.poses_gt_xytheta[0] if tracks.has_ground_truth
                                        else tracks.poses_odom_xytheta[0], dtype=float),
        controls_vw=controls,
        control_covs=np.array([control_noise_cov(u, alpha) for u in controls]).reshape(-1, 2, 2),
        dts_s=np.asarray(tracks.dts, dtype=float),
        observation_ids=tuple(ids for ids, _, _ in frames),
        observations=tuple(z for _, z, _ in frames),
        observation_covs=tuple(R for _, _, R in frames),
    )
