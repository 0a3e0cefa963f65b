"""Depth images of a separate depth camera re-projected into the colour camera (depth registration).

Many RGB-D recordings hold the depth camera's own images (another optical
centre, resolution and intrinsics) rather than depth aligned to colour. Each
depth pixel (u, v) with depth z is back-projected in the depth camera,
X_d = z K_d⁻¹ (u, v, 1)ᵀ, moved into the colour camera, X_c = R X_d + t
(T_color_depth = [R | t]), and projected there, (u', v') = π(K_c X_c), with
the conventions of :mod:`stslam.robot.pinhole` (pixel centres at integer
coordinates; the pinhole model is written out here, the I/O layer being below
the robot models). The pixel's footprint (the box of its corners (u ± ½, v ± ½)
at the same depth, projected to first order) takes every colour pixel whose
centre falls in it, so a coarser depth image leaves no holes, and gives it the
depth z_c of the pixel's centre; where several depth pixels cover a colour pixel, the
nearest surface wins (the smallest z_c, an order-free minimum, so the result
does not depend on the order of the pixels). Colour pixels no depth
pixel covers are NaN, as are depth pixels without a return (NaN or ≤ 0). A
footprint far larger than the image's typical one (a point much nearer the
colour camera than the depth camera) is left out.
"""

from __future__ import annotations

import numpy as np

__all__ = ["register_depth"]

# A footprint wider (in colour pixels, per axis) than the larger of this and FOOTPRINT_SPREAD times the
# median footprint is left out: a coarse depth camera's footprints are all wide, a stray one is not.
MIN_FOOTPRINT_LIMIT_PX = 8
FOOTPRINT_SPREAD = 4


def register_depth(depth_m, K_depth, K_color, T_color_depth, color_size: tuple[int, int]) -> np.ndarray:
    """The depth image ``depth_m`` (H_d, W_d) m of the depth camera as seen by the colour camera.

    ``K_depth``, ``K_color`` (3, 3) pixels; ``T_color_depth`` (4, 4) the depth camera's optical frame in
    the colour camera's; ``color_size`` (width, height) of the colour images. Returns (height, width)
    float32 depths (m, along the colour camera's optical axis), NaN where nothing lands.
    """
    depth = np.asarray(depth_m, dtype=float)
    T = np.asarray(T_color_depth, dtype=float)
    width, height = (int(s) for s in color_size)
    if depth.ndim != 2 or T.shape != (4, 4) or width <= 0 or height <= 0:
        raise ValueError(f"register_depth: expected a 2-D depth image, a 4 × 4 transform and a positive colour "
                         f"size, got shapes {depth.shape}, {T.shape} and size {color_size}")
    v, u = np.nonzero(np.isfinite(depth) & (depth > 0))
    z = depth[v, u]
    out = np.full(height * width, np.inf)
    if z.size:
        R, t = T[:3, :3], T[:3, 3]
        K_d_inv, K_c = np.linalg.inv(np.asarray(K_depth, dtype=float)), np.asarray(K_color, dtype=float)
        rays = np.column_stack([u, v, np.ones_like(z)]) @ K_d_inv.T
        centre = (z[:, None] * rays) @ (K_c @ R).T + K_c @ t  # K_c X_c, X_c = R z K_d⁻¹ (u, v, 1)ᵀ + t (SPEC 15)
        z_color = centre[:, 2]
        # Half the footprint: the projection's first-order change for (u ± ½, v ± ½) at the same depth, whose
        # point moves by z R K_d⁻¹ (±½, ±½, 0)ᵀ: d(a/c) = (da − (a/c) dc)/c per colour coordinate.
        half_u, half_v = (K_c @ R @ K_d_inv @ np.array(e) for e in ((0.5, 0.0, 0.0), (0.0, 0.5, 0.0)))
        with np.errstate(divide="ignore", invalid="ignore"):
            scale = z / z_color
            centre_uv = centre[:, :2] / z_color[:, None]  # (u', v') = π(K_c X_c)
            extent = scale[:, None] * (np.abs(half_u[:2] - centre_uv * half_u[2])
                                       + np.abs(half_v[:2] - centre_uv * half_v[2]))
            ahead = z_color > 0
            # Colour pixel centres c (integers) with min ≤ c < max (half-open: tiling footprints share none).
            low = np.ceil(centre_uv - extent)
            span = np.ceil(centre_uv + extent) - low
        keep = ahead & np.all(np.isfinite(span), axis=1) & np.all(span >= 1, axis=1)
        if keep.any():
            limit = np.maximum(MIN_FOOTPRINT_LIMIT_PX, FOOTPRINT_SPREAD * np.median(span[keep], axis=0))
            keep &= np.all(span <= limit, axis=1)
        low, span, z_color = low[keep].astype(np.int64), span[keep].astype(np.int64), z_color[keep]
        reach = span.max(axis=0) if span.size else np.zeros(2, dtype=np.int64)
        for dy in range(int(reach[1])):
            for dx in range(int(reach[0])):
                inside = (span[:, 0] > dx) & (span[:, 1] > dy)
                col, row = low[inside, 0] + dx, low[inside, 1] + dy
                on_image = (col >= 0) & (col < width) & (row >= 0) & (row < height)
                np.minimum.at(out, row[on_image] * width + col[on_image], z_color[inside][on_image])
    out[~np.isfinite(out)] = np.nan
    return out.reshape(height, width).astype(np.float32)
