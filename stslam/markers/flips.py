"""Choosing one pose per frame so that the track does not flip (SPEC 17).

Each frame offers a few candidate poses (IPPE's two, or four when taken
relative to a reference marker; :mod:`stslam.markers.pose`). The choice is
the sequence c_1 … c_n that minimises, by dynamic programming (Viterbi),

    Σ_k  2 (e²(c_k) − e²_min,k) / σ_px²                        (reprojection: 4 corners × 2 coordinates, halved)
  + Σ_k  ∠(R(c_{k−1}), R(c_k))² / (2 σ_turn² g_k)               (a rigid body turns smoothly)

with e the RMS reprojection error (px), ∠ the angle between two rotations,
σ_turn the turn allowed per frame (rad) and g_k the frame gap between
consecutive detections (a random walk of the orientation: variance grows
with the gap). A clearly better reprojection wins on its own; where both
solutions explain the corners alike, the one that continues the track does.
A frame whose chosen pose is not its best-reprojecting one is a *flip*
avoided.
"""

from __future__ import annotations

import numpy as np

from stslam.checks import check_number


def rotation_angles(Ra, Rb) -> np.ndarray:
    """Angles (rad) between every rotation of ``Ra`` (a, 3, 3) and of ``Rb`` (b, 3, 3): shape (a, b).

    ∠(A, B) = arccos((tr(Aᵀ B) − 1) / 2).
    """
    traces = np.einsum("aij,bij->ab", np.asarray(Ra, dtype=float), np.asarray(Rb, dtype=float))
    return np.arccos(np.clip(0.5 * (traces - 1.0), -1.0, 1.0))


def choose_poses(candidates, frames, *, sigma_px: float = 0.5, sigma_turn_deg: float = 4.0) -> np.ndarray:
    """Index of the chosen candidate of each frame (module docstring).

    Parameters
    ----------
    candidates : sequence of PoseCandidates
        Per detection (in time order), at least one candidate each.
    frames : array_like, shape (n,)
        Frame number of each detection, strictly increasing.
    sigma_px : float
        Corner noise (px) of the reprojection term.
    sigma_turn_deg : float
        Turn allowed between consecutive frames (deg).
    """
    frames = np.asarray(frames, dtype=int).reshape(-1)
    if frames.size != len(candidates) or (frames.size > 1 and np.any(np.diff(frames) <= 0)):
        raise ValueError(f"frames: expected {len(candidates)} strictly increasing frame numbers")
    if any(len(c) == 0 for c in candidates):
        raise ValueError("candidates: every detection needs at least one pose")
    sigma_px = check_number("sigma_px", sigma_px, low=0.0, low_open=True)
    sigma_turn = np.radians(check_number("sigma_turn_deg", sigma_turn_deg, low=0.0, low_open=True))
    if frames.size == 0:
        return np.zeros(0, dtype=int)
    unary = [2.0 * (c.error_px**2 - np.min(c.error_px) ** 2) / sigma_px**2 for c in candidates]
    cost = unary[0].copy()
    back = []
    for k in range(1, len(candidates)):
        gap = float(frames[k] - frames[k - 1])
        turn = rotation_angles(candidates[k - 1].R, candidates[k].R) ** 2 / (2.0 * sigma_turn**2 * gap)
        total = cost[:, None] + turn
        back.append(np.argmin(total, axis=0))
        cost = total[back[-1], np.arange(total.shape[1])] + unary[k]
    chosen = np.empty(len(candidates), dtype=int)
    chosen[-1] = int(np.argmin(cost))
    for k in range(len(candidates) - 1, 0, -1):
        chosen[k - 1] = back[k - 1][chosen[k]]
    return chosen
