"""A marker's pose track from its detections in every frame (SPEC 17).

Per frame with the marker (and, when given, the reference marker) detected,
the IPPE candidates of :mod:`stslam.markers.pose` (relative to the reference
when there is one), then one candidate per frame chosen over the whole track
by :func:`stslam.markers.flips.choose_poses`. The reporting frame is the
camera's, or the reference marker's.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from stslam.markers.flips import choose_poses
from stslam.markers.pose import ippe_candidates, relative_candidates


@dataclass(frozen=True)
class MarkerTrack:
    """The chosen poses: ``frames`` (n,) frame numbers, rotations ``R`` (n, 3, 3) and centres ``t`` (n, 3) m
    of the marker in the reporting frame; ``T_camera_frame`` (n, 4, 4): the reporting frame in the camera's
    at each of those frames (identity without a reference); ``flips``: frames whose chosen pose is not
    their best-reprojecting one."""

    frames: np.ndarray
    R: np.ndarray
    t: np.ndarray
    T_camera_frame: np.ndarray
    flips: int


def most_seen_id(detections, exclude=None) -> int | None:
    """The id found in the most frames of ``detections`` (a list of {id: corners}), ties to the smaller id;
    ``exclude`` (e.g. the reference) is not counted; None when no other marker was found."""
    counts = Counter(i for found in detections for i in found if i != exclude)
    if not counts:
        return None
    return min(counts, key=lambda i: (-counts[i], i))


def pose_track(detections, marker_id: int, K, D, length_m: float, reference_id: int | None = None, *,
               sigma_px: float = 0.5, sigma_turn_deg: float = 4.0) -> MarkerTrack:
    """The pose track (module docstring) of ``marker_id`` through ``detections`` ({id: corners (4, 2) px} per
    frame, frame k at index k), with intrinsics K (3, 3), distortion D and the marker side ``length_m`` (m;
    the reference marker is taken to be of the same size)."""
    frames, candidates, references = [], [], []
    for k, found in enumerate(detections):
        if marker_id not in found or (reference_id is not None and reference_id not in found):
            continue
        moving = ippe_candidates(found[marker_id], K, D, length_m)
        reference = None
        if reference_id is not None:
            reference = ippe_candidates(found[reference_id], K, D, length_m)
            moving = relative_candidates(reference, moving)
        if len(moving):
            frames.append(k)
            candidates.append(moving)
            references.append(reference)
    if not frames:
        return MarkerTrack(np.zeros(0, int), np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros((0, 4, 4)), 0)
    chosen = choose_poses(candidates, frames, sigma_px=sigma_px, sigma_turn_deg=sigma_turn_deg)
    R = np.array([c.R[j] for c, j in zip(candidates, chosen)])
    t = np.array([c.t[j] for c, j in zip(candidates, chosen)])
    T = np.repeat(np.eye(4)[None], len(frames), axis=0)
    if reference_id is None:
        flips = int(np.count_nonzero(chosen != 0))
    else:
        n_moving = [len(c) // len(r) for c, r in zip(candidates, references)]
        i_ref, j_mov = chosen // np.array(n_moving), chosen % np.array(n_moving)
        flips = int(np.count_nonzero(j_mov != 0) + np.count_nonzero(i_ref != 0))
        for k, (r, i) in enumerate(zip(references, i_ref)):
            T[k, :3, :3], T[k, :3, 3] = r.R[i], r.t[i]
    return MarkerTrack(np.array(frames), R, t, T, flips)
