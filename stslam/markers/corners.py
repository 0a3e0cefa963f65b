"""Marker corners from its four edges: sub-pixel, unbiased under blur and lens distortion (SPEC 17).

OpenCV's ArUco corners lie on the dark side of the marker's outline: half a
pixel inside without refinement, 0.1–0.2 px with ``CORNER_REFINE_SUBPIX``
(measured on rendered markers). At 30 px across that makes the marker 1–3 %
small, i.e. its distance 1–3 % long: centimetres at a couple of metres, all in
one direction. Here each side is located where the image crosses halfway
between the black border and the white margin (a symmetric blur leaves that
crossing on the true edge):

1. along each side, at ``samples`` places between 15 % and 85 % of its
   length, the intensity profile across it (bilinear, 0.25 px steps), inwards
   up to ``inner_cells`` border cells and outwards as far;
2. the edge point: where the profile crosses the mean of its innermost and
   outermost values, nearest the detected side (skipped when their contrast is
   below ``min_contrast`` grey levels);
3. the points are undistorted (ideal pinhole pixels, ``cv2.undistortPoints``),
   a line is fitted to each side by total least squares, adjacent lines are
   intersected and the corners distorted back (``cv2.projectPoints``).

Where a side has fewer than 3 edge points, or a corner would move by more than
``max_shift_cells`` of a cell, the detected corners are returned unchanged.
"""

from __future__ import annotations

import cv2
import numpy as np

STEP_PX = 0.25


def _profiles(grey: np.ndarray, points: np.ndarray, normal: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Intensities (m, k) at points (m, 2) + offsets (k,) × normal (2,), bilinear."""
    xy = points[:, None, :] + offsets[None, :, None] * normal[None, None, :]
    return cv2.remap(grey, xy[..., 0].astype(np.float32), xy[..., 1].astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_REPLICATE)


def _crossings(profiles: np.ndarray, offsets: np.ndarray, min_contrast: float) -> np.ndarray:
    """Offset (m,) where each profile crosses halfway between its ends, nearest 0; NaN where there is none."""
    inner, outer = profiles[:, :2].mean(axis=1), profiles[:, -2:].mean(axis=1)
    mid = 0.5 * (inner + outer)
    above = profiles > mid[:, None]
    change = above[:, 1:] != above[:, :-1]
    out = np.full(profiles.shape[0], np.nan)
    centre = np.abs(0.5 * (offsets[1:] + offsets[:-1]))
    for i in np.flatnonzero((outer - inner) >= min_contrast):
        j = np.flatnonzero(change[i])
        if j.size == 0:
            continue
        j = j[np.argmin(centre[j])]
        a, b = profiles[i, j] - mid[i], profiles[i, j + 1] - mid[i]
        out[i] = offsets[j] + STEP_PX * a / (a - b)
    return out


def _line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Total-least-squares line of points (m, 2): a point on it and its unit normal."""
    centre = points.mean(axis=0)
    return centre, np.linalg.svd(points - centre, full_matrices=False)[2][1]


def refine_corners(grey, corners_px, K, D, cells: int, *, samples: int = 24, inner_cells: float = 0.7,
                   min_contrast: float = 10.0, max_shift_cells: float = 0.35) -> np.ndarray:
    """Corners (4, 2) px of a detected marker (OpenCV's order) located from its edges (module docstring).

    ``grey``: the image (H, W) uint8 or float; ``K``, ``D``: the camera; ``cells``: bits across the marker
    including its black border (the dictionary's marker size + 2).
    """
    corners = np.asarray(corners_px, dtype=float).reshape(4, 2)
    grey = np.asarray(grey, dtype=np.float32)
    side_px = np.mean(np.linalg.norm(np.roll(corners, -1, axis=0) - corners, axis=1))
    cell = side_px / cells
    reach = max(1.0, inner_cells * cell)
    offsets = np.arange(-reach, reach + 1e-9, STEP_PX)
    centroid = corners.mean(axis=0)
    K = np.asarray(K, dtype=float)
    D = np.asarray(D, dtype=float).reshape(-1)
    lines = []
    for i in range(4):
        p0, p1 = corners[i], corners[(i + 1) % 4]
        direction = (p1 - p0) / np.linalg.norm(p1 - p0)
        normal = np.array([-direction[1], direction[0]])
        if normal @ (0.5 * (p0 + p1) - centroid) < 0:
            normal = -normal  # outwards: dark (border) at negative offsets, light (margin) at positive
        along = p0 + np.outer(np.linspace(0.15, 0.85, samples), p1 - p0)
        shift = _crossings(_profiles(grey, along, normal, offsets), offsets, min_contrast)
        good = np.isfinite(shift)
        if good.sum() < 3:
            return corners
        edge = along[good] + np.outer(shift[good], normal)
        ideal = cv2.undistortPoints(edge.reshape(-1, 1, 2), K, D, P=K).reshape(-1, 2)
        lines.append(_line(ideal))
    refined = []
    for i in range(4):
        (c1, n1), (c2, n2) = lines[i - 1], lines[i]  # side i − 1 ends and side i starts at corner i
        A = np.array([n1, n2])
        if abs(np.linalg.det(A)) < 1e-6:
            return corners
        refined.append(np.linalg.solve(A, [n1 @ c1, n2 @ c2]))
    ideal = np.array(refined)
    rays = np.column_stack([ideal, np.ones(4)]) @ np.linalg.inv(K).T
    out, _ = cv2.projectPoints(rays, np.zeros(3), np.zeros(3), K, D)
    out = out.reshape(4, 2)
    if np.max(np.linalg.norm(out - corners, axis=1)) > max_shift_cells * cell + 0.5:
        return corners
    return out
