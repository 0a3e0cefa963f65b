"""SLAM over a planar robot's pose from RGB-D feature tracks (SPEC 5.2, 6, 8.5).

The filters are those of ``dynamic_slam`` (:mod:`stslam.slam`): this module
only turns a recording's tracks into their inputs and drives them.

* **Observations.** The camera mount carries each camera-frame point into the
  robot frame, z = R_bc X_c + t_bc, which is exactly SPEC 5.2's
  z = R(θ)ᵀ(m − [x, y, 0]ᵀ) for the landmark's world point m; its noise
  R = R_bc Σ_c R_bcᵀ comes per observation from the depth model
  (:mod:`stslam.feature_tracks`).
* **Controls.** The odometry poses of consecutive frames give the control
  (v, ω) by inverting SPEC 5.1 (:func:`stslam.robot.control_between`), with
  δt from the time stamps; the filters assume S(û) with the configured α.
* **Landmarks.** A track is a landmark with its id (data association by the
  tracker). To bound the state, only tracks with at least
  ``min_track_frames`` 3D observations take part, the longest
  ``max_landmarks`` of them (ties by id): the paper kept only long tracks too
  (SPEC 8.5).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from stslam.rgbd_tracks import SequenceTracks
from stslam.robot import control_between, control_noise_cov
from stslam.slam.core import SlamState
from stslam.slam.filters import FilterSpec, FilterTrack


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


def run_rgbd_filter(spec: FilterSpec, tracks: SequenceTracks, inputs: list, alpha,
                    after_frame: Callable | None = None) -> FilterTrack:
    """Run a ``dynamic_slam`` filter over a recording, from the true first pose (known, P = 0).

    Frame 0: observe. Frame k ≥ 1: predict with the odometry control of step
    k − 1 over its δt and S(û) (SPEC 5.1); update with each observation of a
    landmark already in the state with its own R (one EKF update each, gated
    on its NIS if the filter gates); then add the frame's new landmarks with
    the filter's block. ``after_frame(k, state, ids, z, R)``, if given, is called
    after each frame's updates with the frame's landmark ids, observations and noises:
    the hook through which A-SLAM (:mod:`stslam.rgbd_aslam`) converts blocks.
    """
    controls = odometry_controls(tracks.poses_odom_xytheta, tracks.times_s)
    dts = tracks.dts
    n = tracks.n_frames
    state = SlamState(tracks.poses_gt_xytheta[0], np.zeros((3, 3)))
    poses = np.empty((n, 3))
    covs = np.empty((n, 3, 3))
    rejected = 0
    for k in range(n):
        if k > 0:
            state.predict(controls[k - 1], control_noise_cov(controls[k - 1], alpha), float(dts[k - 1]))
        ids, z, R = inputs[k]
        for j, i in enumerate(ids.tolist()):
            if i in state:
                rejected += int(not state.update_landmark(i, z[j], R[j], spec.max_nis).accepted)
        for j, i in enumerate(ids.tolist()):
            if i not in state:
                state.add_landmark(i, spec.block_for(i), z[j], R[j])
        if after_frame is not None:
            after_frame(k, state, ids, z, R)
        poses[k] = state.pose
        covs[k] = state.pose_cov
    return FilterTrack(poses, covs, rejected)
