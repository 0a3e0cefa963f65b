"""The pose of a square marker from its four corners: both solutions of IPPE (SPEC 17).

A square seen by a calibrated camera has, in general, two poses that explain
its corners almost equally well (the plane tilted one way or mirrored about
the line of sight); ``cv2.solvePnPGeneric`` with ``SOLVEPNP_IPPE_SQUARE`` gives
both, with their reprojection errors, using the lens distortion. Which one is
right is decided over the track (:mod:`stslam.markers.flips`), not per frame.

Marker frame (OpenCV's): origin at the centre, x to the right and y up as
printed, z out of the printed face; corners at (∓L/2, ±L/2, 0) in the order
top-left, top-right, bottom-right, bottom-left. A pose (R, t) maps marker
points into the camera frame: X_cam = R X_marker + t (m).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stslam.checks import check_number


@dataclass(frozen=True)
class PoseCandidates:
    """The poses that explain one detection, best first: rotations (k, 3, 3), translations (k, 3) m and
    reprojection errors (k,) px (RMS over the corners)."""

    R: np.ndarray
    t: np.ndarray
    error_px: np.ndarray

    def __len__(self) -> int:
        return self.R.shape[0]


def marker_object_points(length_m: float) -> np.ndarray:
    """Corners (4, 3) of a marker of side ``length_m`` in its own frame (module docstring), m."""
    half = 0.5 * check_number("marker_length", length_m, low=0.0, low_open=True)
    return np.array([[-half, half, 0.0], [half, half, 0.0], [half, -half, 0.0], [-half, -half, 0.0]])


def ippe_candidates(corners_px, K, D, length_m: float, max_error_px: float = 4.0) -> PoseCandidates:
    """Both IPPE poses (module docstring) of a marker with image corners (4, 2) px, intrinsics K (3, 3) and
    distortion D (OpenCV's order), sorted by reprojection error; an empty set when IPPE finds none.

    A pose that misses the corners by more than ``max_error_px`` (RMS), or 5 % of the marker's side if
    that is more, is none: IPPE's homography degenerates for a marker seen exactly face-on and returns
    nonsense there (measured: 64 px off a 90 px marker).
    """
    corners = np.asarray(corners_px, dtype=float).reshape(4, 1, 2)
    objects = marker_object_points(length_m)
    n, rvecs, tvecs, errors = cv2.solvePnPGeneric(objects, corners, np.asarray(K, dtype=float),
                                                  np.asarray(D, dtype=float).reshape(-1),
                                                  flags=cv2.SOLVEPNP_IPPE_SQUARE)
    if not n:
        return PoseCandidates(np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0))
    R = np.array([cv2.Rodrigues(np.asarray(r, dtype=float))[0] for r in rvecs[:n]])
    t = np.array([np.asarray(v, dtype=float).reshape(3) for v in tvecs[:n]])
    e = np.asarray(errors, dtype=float).reshape(-1)[:n]
    side_px = float(np.mean(np.linalg.norm(np.roll(corners[:, 0], -1, axis=0) - corners[:, 0], axis=1)))
    keep = (t[:, 2] > 0) & (e <= max(max_error_px, 0.05 * side_px))  # nor is a marker behind the camera
    order = np.argsort(e[keep], kind="stable")
    return PoseCandidates(R[keep][order], t[keep][order], e[keep][order])


def relative_candidates(reference: PoseCandidates, marker: PoseCandidates) -> PoseCandidates:
    """Every pairing of a reference marker's poses with a moving marker's: the moving marker in the reference's
    frame, R = R_refᵀ R_m, t = R_refᵀ (t_m − t_ref); the error is the larger of the two (px); pairs in the
    order (reference i, marker j), i major."""
    R, t, e = [], [], []
    for i in range(len(reference)):
        Rr, tr = reference.R[i], reference.t[i]
        for j in range(len(marker)):
            R.append(Rr.T @ marker.R[j])
            t.append(Rr.T @ (marker.t[j] - tr))
            e.append(max(reference.error_px[i], marker.error_px[j]))
    if not R:
        return PoseCandidates(np.zeros((0, 3, 3)), np.zeros((0, 3)), np.zeros(0))
    return PoseCandidates(np.array(R), np.array(t), np.array(e))


def project_points(points_cam, K, D) -> np.ndarray:
    """Pixels (n, 2) of camera-frame points (n, 3) m through K and the lens distortion D."""
    P = np.asarray(points_cam, dtype=float).reshape(-1, 1, 3)
    uv, _ = cv2.projectPoints(P, np.zeros(3), np.zeros(3), np.asarray(K, dtype=float),
                              np.asarray(D, dtype=float).reshape(-1))
    return uv.reshape(-1, 2)
