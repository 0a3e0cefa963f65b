"""RGB-D feature tracks: corners tracked by pyramidal Lucas–Kanade and lifted to 3D (SPEC 8.5, 9).

The front end of the ``fridge`` experiment, in the spirit of the paper's
Pillai-style pipeline (good features to track, matched between frames, depth
up to 4 m):

1. **Detect** Shi–Tomasi corners (``cv2.goodFeaturesToTrack``, quality level
   0.02 as in the paper, SPEC 8.5) in a mask that keeps ``min_distance_px``
   away from the live tracks, whenever fewer than ``redetect_fraction`` ·
   ``target_tracks`` tracks are alive; each new corner starts a track with a
   new integer id. Detection is bucketed: the image is cut into
   ``grid_cols`` × ``grid_rows`` cells and each cell is topped up to its share
   of ``target_tracks`` with its own strongest corners, so one richly textured
   object (the door's magnets) cannot take every track.
2. **Track** every live corner into the next image with pyramidal LK
   (``cv2.calcOpticalFlowPyrLK``) and back again; a track survives when both
   directions converge, the forward–backward distance is below
   ``fb_max_px`` and the point stays inside the image.
3. **Depth**: the median of the valid depths in a (2h+1)² window around the
   rounded pixel; no depth (NaN, out of [depth_min_m, depth_max_m], fewer than
   half the window valid, or a spread max − min above ``max_depth_spread_m``:
   a depth edge) gives no 3D observation in that frame but the 2D track goes on.
   A track whose camera-frame point jumps by more than ``max_jump_m`` per frame
   since its last 3D observation is ended: its corner slid along an occlusion
   edge onto another surface (a door edge passing over the wall behind it).
4. **Back-project** with K: X_c = z K⁻¹ (u, v, 1)ᵀ (:mod:`stslam.robot.pinhole`),
   with the covariance of (u, v, z) ~ N(·, diag(σ_px², σ_px², σ_z²)),
   σ_z = c z² (the structured-light depth model of SPEC 9), carried to X_c by
   the Jacobian J = ∂X_c/∂(u, v, z) = [[z/fx, 0, x̄], [0, z/fy, ȳ], [0, 0, 1]]
   with (x̄, ȳ) = ((u − cx)/fx, (v − cy)/fy): Σ_c = J diag(…) Jᵀ (camera frame).

Pure functions do each step on arrays; :class:`FeatureTracker` keeps the
previous grey image and the live tracks between frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stslam.geometry import depth_noise_std


@dataclass(frozen=True)
class TrackerSettings:
    """Front-end parameters (pixels, metres); see the module docstring for each step."""

    target_tracks: int = 150
    redetect_fraction: float = 0.9
    quality_level: float = 0.02
    grid_cols: int = 4
    grid_rows: int = 3
    min_distance_px: float = 8.0
    block_size: int = 7
    window_px: int = 21
    pyramid_levels: int = 3
    fb_max_px: float = 1.0
    depth_half_window_px: int = 2
    depth_min_m: float = 0.3
    depth_max_m: float = 4.0
    max_depth_spread_m: float = 0.08
    max_jump_m: float = 0.1
    pixel_sigma_px: float = 1.0
    depth_noise_coefficient: float = 1.5e-3


@dataclass(frozen=True)
class FrameObservations:
    """The 3D observations of one frame.

    Attributes
    ----------
    track_ids : numpy.ndarray of int, shape (k,)
    pixels_uv : numpy.ndarray, shape (k, 2)
        Tracked pixel positions (column, row).
    points_camera : numpy.ndarray, shape (k, 3)
        Back-projected points (m, camera optical frame).
    covs_camera : numpy.ndarray, shape (k, 3, 3)
        Their covariances (m², camera optical frame).
    n_live : int
        Live 2D tracks, with or without depth in this frame.
    """

    track_ids: np.ndarray
    pixels_uv: np.ndarray
    points_camera: np.ndarray
    covs_camera: np.ndarray
    n_live: int


# ----------------------------------------------------------------------------- pure steps

def grey_image(rgb) -> np.ndarray:
    """uint8 grey image (H, W) of an RGB image (H, W, 3)."""
    return cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.uint8), cv2.COLOR_RGB2GRAY)


def detection_mask(shape_hw, pixels_uv, radius_px: float) -> np.ndarray:
    """uint8 mask (H, W): 255 except within ``radius_px`` of any of ``pixels_uv`` (k, 2)."""
    mask = np.full(shape_hw, 255, dtype=np.uint8)
    r = max(1, int(round(radius_px)))
    for u, v in np.rint(np.asarray(pixels_uv, dtype=float).reshape(-1, 2)).astype(int):
        cv2.circle(mask, (int(u), int(v)), r, 0, -1)
    return mask


def detect_corners(grey, max_corners: int, settings: TrackerSettings, mask=None) -> np.ndarray:
    """Shi–Tomasi corners (n, 2) (u, v pixels), strongest first; at most ``max_corners``."""
    if max_corners <= 0:
        return np.empty((0, 2))
    found = cv2.goodFeaturesToTrack(grey, maxCorners=int(max_corners), qualityLevel=settings.quality_level,
                                    minDistance=settings.min_distance_px, mask=mask,
                                    blockSize=settings.block_size)
    return np.empty((0, 2)) if found is None else found.reshape(-1, 2).astype(float)


def detect_bucketed(grey, pixels_uv, settings: TrackerSettings) -> np.ndarray:
    """New corners (n, 2): each grid cell topped up to ⌈target/cells⌉ tracks, away from ``pixels_uv``."""
    h, w = grey.shape
    mask = detection_mask((h, w), pixels_uv, settings.min_distance_px)
    cols, rows = settings.grid_cols, settings.grid_rows
    share = -(-settings.target_tracks // (cols * rows))
    uv = np.asarray(pixels_uv, dtype=float).reshape(-1, 2)
    cell_of = (np.minimum((uv[:, 1] * rows / h).astype(int), rows - 1) * cols
               + np.minimum((uv[:, 0] * cols / w).astype(int), cols - 1))
    counts = np.bincount(cell_of, minlength=cols * rows)
    found = []
    for r in range(rows):
        for c in range(cols):
            wanted = share - counts[r * cols + c]
            if wanted <= 0:
                continue
            v0, v1 = r * h // rows, (r + 1) * h // rows
            u0, u1 = c * w // cols, (c + 1) * w // cols
            corners = detect_corners(grey[v0:v1, u0:u1], wanted, settings, mask[v0:v1, u0:u1])
            found.append(corners + [u0, v0])
    return np.vstack(found) if found else np.empty((0, 2))


def track_forward_backward(grey_prev, grey_next, pixels_uv, settings: TrackerSettings) -> tuple[np.ndarray, np.ndarray]:
    """LK from the previous to the next image and back; tracked pixels (n, 2) and an ok mask (n,).

    ok: both directions converged, |p − back(forward(p))| < ``fb_max_px`` and
    the tracked point lies inside the image.
    """
    p0 = np.asarray(pixels_uv, dtype=np.float32).reshape(-1, 1, 2)
    if p0.shape[0] == 0:
        return np.empty((0, 2)), np.zeros(0, dtype=bool)
    size = (settings.window_px, settings.window_px)
    criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 20, 0.03)
    p1, st1, _ = cv2.calcOpticalFlowPyrLK(grey_prev, grey_next, p0, None, winSize=size,
                                          maxLevel=settings.pyramid_levels, criteria=criteria)
    p0b, st0, _ = cv2.calcOpticalFlowPyrLK(grey_next, grey_prev, p1, None, winSize=size,
                                           maxLevel=settings.pyramid_levels, criteria=criteria)
    fb = np.linalg.norm((p0 - p0b).reshape(-1, 2), axis=1)
    p1 = p1.reshape(-1, 2).astype(float)
    h, w = grey_next.shape[:2]
    inside = (p1[:, 0] >= 0) & (p1[:, 0] <= w - 1) & (p1[:, 1] >= 0) & (p1[:, 1] <= h - 1)
    ok = (st1.reshape(-1) == 1) & (st0.reshape(-1) == 1) & (fb < settings.fb_max_px) & inside
    return p1, ok


def lookup_depth(depth_m, pixels_uv, settings: TrackerSettings) -> tuple[np.ndarray, np.ndarray]:
    """Depth z (n,) m at pixels (n, 2) and a valid mask (n,) (step 3 of the module docstring).

    Window pixels outside the image count as invalid. Invalid entries of z are NaN.
    """
    depth = np.asarray(depth_m, dtype=np.float32)
    uv = np.rint(np.asarray(pixels_uv, dtype=float).reshape(-1, 2)).astype(int)
    n = uv.shape[0]
    if n == 0:
        return np.empty(0), np.zeros(0, dtype=bool)
    h, w = depth.shape
    half = settings.depth_half_window_px
    offsets = np.arange(-half, half + 1)
    rows = uv[:, 1, None, None] + offsets[None, :, None]
    cols = uv[:, 0, None, None] + offsets[None, None, :]
    inside = (rows >= 0) & (rows < h) & (cols >= 0) & (cols < w)
    window = depth[np.clip(rows, 0, h - 1), np.clip(cols, 0, w - 1)].reshape(n, -1).astype(float)
    window[~inside.reshape(n, -1)] = np.nan
    window[(window < settings.depth_min_m) | (window > settings.depth_max_m)] = np.nan
    n_valid = np.sum(np.isfinite(window), axis=1)
    enough = 2 * n_valid >= window.shape[1]
    z = np.full(n, np.nan)
    spread = np.full(n, np.inf)
    if enough.any():
        z[enough], low, high = nan_median_range(window[enough], n_valid[enough])
        spread[enough] = high - low
    ok = enough & (spread <= settings.max_depth_spread_m)
    z[~ok] = np.nan
    return z, ok


def nan_median_range(rows, n_valid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Median, minimum and maximum (each (n,)) of each row of ``rows`` (n, m) over its ``n_valid`` (n,) finite
    entries (each ≥ 1; the others NaN): ``np.nanmedian``, ``np.nanmin`` and ``np.nanmax`` along axis 1, to the
    bit (the median of an even count is the mean of its two middle values, as numpy's), from one sort in
    which the NaNs go last (numpy's nanmedian masks each row instead, ~10 times slower on a frame's tracks)."""
    ordered = np.sort(rows, axis=1)
    r = np.arange(ordered.shape[0])
    middle = (ordered[r, (n_valid - 1) // 2] + ordered[r, n_valid // 2]) / 2.0
    return middle, ordered[:, 0], ordered[r, n_valid - 1]


def back_project_with_covariance(K, pixels_uv, depth_m, pixel_sigma_px: float,
                                 depth_noise_coefficient: float) -> tuple[np.ndarray, np.ndarray]:
    """Camera-frame points (n, 3) m and covariances (n, 3, 3) m² of pixels at depth z (step 4).

    X_c = z K⁻¹ (u, v, 1)ᵀ; Σ_c = J diag(σ_px², σ_px², (c z²)²) Jᵀ with
    J = ∂X_c/∂(u, v, z) (module docstring; SPEC 9 depth model).
    """
    K = np.asarray(K, dtype=float)
    uv = np.asarray(pixels_uv, dtype=float).reshape(-1, 2)
    z = np.asarray(depth_m, dtype=float).reshape(-1)
    fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
    xb = (uv[:, 0] - cx) / fx
    yb = (uv[:, 1] - cy) / fy
    points = np.column_stack([xb * z, yb * z, z])
    J = np.zeros((z.size, 3, 3))
    J[:, 0, 0] = z / fx
    J[:, 1, 1] = z / fy
    J[:, 0, 2] = xb
    J[:, 1, 2] = yb
    J[:, 2, 2] = 1.0
    sigma_z = depth_noise_std(z, depth_noise_coefficient)  # SPEC 9
    D = np.zeros((z.size, 3, 3))
    D[:, 0, 0] = D[:, 1, 1] = pixel_sigma_px**2
    D[:, 2, 2] = sigma_z**2
    covs = J @ D @ np.transpose(J, (0, 2, 1))
    return points, covs


# ----------------------------------------------------------------------------- the tracker

class FeatureTracker:
    """Frame-to-frame corner tracks with depth (module docstring). Call :meth:`step` per frame.

    Parameters
    ----------
    settings : TrackerSettings
    """

    def __init__(self, settings: TrackerSettings):
        self.settings = settings
        self._grey = None
        self._shape = None
        self._pixels = np.empty((0, 2))
        self._ids = np.empty(0, dtype=int)
        self._next_id = 0
        self._frame = -1
        self._last_point: dict[int, tuple[int, np.ndarray]] = {}  # id -> (frame, camera-frame point)

    @property
    def n_started(self) -> int:
        """Tracks started so far (ids 0 … n_started − 1)."""
        return self._next_id

    def step(self, rgb, depth_m, K) -> FrameObservations:
        """Track into this frame, top up the tracks and return the frame's 3D observations.

        ``rgb`` (H, W, 3) uint8, ``depth_m`` (H, W) metres (NaN = no return), ``K`` (3, 3).
        """
        s = self.settings
        self._frame += 1
        grey = grey_image(rgb)
        shape = grey.shape
        if self._grey is not None and self._shape == shape and self._ids.size:
            pixels, ok = track_forward_backward(self._grey, grey, self._pixels, s)
            self._pixels, self._ids = pixels[ok], self._ids[ok]
        elif self._shape != shape:
            self._pixels, self._ids = np.empty((0, 2)), np.empty(0, dtype=int)
        if self._ids.size < s.redetect_fraction * s.target_tracks or self._ids.size == 0:
            new = detect_bucketed(grey, self._pixels, s)
            self._pixels = np.vstack([self._pixels, new])
            self._ids = np.concatenate([self._ids, self._next_id + np.arange(new.shape[0])])
            self._next_id += new.shape[0]
        self._grey, self._shape = grey, shape
        z, valid = lookup_depth(depth_m, self._pixels, s)
        points, covs = back_project_with_covariance(K, self._pixels[valid], z[valid], s.pixel_sigma_px,
                                                    s.depth_noise_coefficient)
        ids, pixels = self._ids[valid], self._pixels[valid]
        keep = self._continuous(ids, points)
        if not keep.all():
            ended = set(ids[~keep].tolist())
            alive = np.array([i not in ended for i in self._ids], dtype=bool)
            self._pixels, self._ids = self._pixels[alive], self._ids[alive]
            for i in ended:
                self._last_point.pop(i, None)
        live = set(self._ids.tolist())
        self._last_point = {i: v for i, v in self._last_point.items() if i in live}
        for i, p in zip(ids[keep], points[keep]):
            self._last_point[int(i)] = (self._frame, p)
        return FrameObservations(track_ids=ids[keep].copy(), pixels_uv=pixels[keep].copy(),
                                 points_camera=points[keep], covs_camera=covs[keep], n_live=int(self._ids.size))

    def _continuous(self, ids, points) -> np.ndarray:
        """Mask (k,): the point moved at most ``max_jump_m`` per frame since the track's last 3D point."""
        keep = np.ones(ids.size, dtype=bool)
        known = [(j, last) for j, i in enumerate(ids.tolist()) if (last := self._last_point.get(i)) is not None]
        if known:  # all at once: ‖d‖ as (d·d summed)^½, the bits np.linalg.norm gives each on its own
            rows = np.array([j for j, _ in known])
            moved = points[rows] - np.array([last[1] for _, last in known])
            frames = self._frame - np.array([last[0] for _, last in known])
            keep[rows] = np.sqrt((moved * moved).sum(axis=1)) <= self.settings.max_jump_m * frames
        return keep
