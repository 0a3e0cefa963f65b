"""Depth images of a separate depth camera re-projected into the colour camera (depth registration).

Many RGB-D recordings hold the depth camera's own images (another optical
centre, resolution and intrinsics) rather than depth aligned to colour. Each
depth pixel (u, v) with depth z is back-projected in the depth camera,
X_d = z K_d⁻¹ (u, v, 1)ᵀ, moved into the colour camera, X_c = R X_d + t
(T_color_depth = [R | t]), and projected there, (u', v') = π(K_c X_c), with
the conventions of :mod:`stslam.robot.pinhole` (pixel centres at integer
coordinates; the pinhole model is written out here, the I/O layer being below
the robot models). The pixel's footprint (the box of its corners (u ± ½, v ± ½)
projected at the same depth) takes every colour pixel whose centre falls in
it, so a coarser depth image leaves no holes, and gives it the depth z_c of
the pixel's centre; where several depth pixels cover a colour pixel, the
nearest surface wins (the smallest z_c, an order-free minimum, so the result
does not depend on the order of the pixels). Colour pixels no depth
pixel covers are NaN, as are depth pixels without a return (NaN or ≤ 0).
"""

from __future__ import annotations

import numpy as np


__all__ = ["register_depth"]

MAX_FOOTPRINT_PX = 8  # a depth pixel covering more colour pixels than this across is left out (a grazing surface)


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

        def to_color(du: float, dv: float):
            """Colour pixels (n, 2) and z_c (n,) of each depth pixel's point (u + du, v + dv) at its depth z."""
            pixels = np.column_stack([u + du, v + dv, np.ones_like(z)])
            points = (pixels @ K_d_inv.T) * z[:, None] @ R.T + t  # X_c = R z K_d⁻¹ (u, v, 1)ᵀ + t (SPEC 15)
            with np.errstate(divide="ignore", invalid="ignore"):
                return (points @ K_c.T)[:, :2] / points[:, 2:3], points[:, 2]  # (u', v') = π(K_c X_c)

        _, z_color = to_color(0.0, 0.0)
        corners = [to_color(du, dv) for du, dv in ((-0.5, -0.5), (0.5, 0.5), (-0.5, 0.5), (0.5, -0.5))]
        uv = np.stack([c[0] for c in corners])  # (4, n, 2)
        ahead = np.all(np.stack([c[1] for c in corners]) > 0, axis=0) & (z_color > 0)
        # Colour pixel centres c (integers) with min ≤ c < max (half-open: tiling footprints share none).
        with np.errstate(invalid="ignore"):
            low = np.ceil(uv.min(axis=0))
            high = np.ceil(uv.max(axis=0)) - 1
        span = high - low + 1
        keep = ahead & np.all(np.isfinite(span), axis=1) & np.all(span >= 1, axis=1) & \
            np.all(span <= MAX_FOOTPRINT_PX, axis=1)
        low, span, z_color = low[keep].astype(np.int64), span[keep].astype(np.int64), z_color[keep]
        for dy in range(MAX_FOOTPRINT_PX):
            for dx in range(MAX_FOOTPRINT_PX):
                inside = (span[:, 0] > dx) & (span[:, 1] > dy)
                if not inside.any():
                    continue
                col, row = low[inside, 0] + dx, low[inside, 1] + dy
                on_image = (col >= 0) & (col < width) & (row >= 0) & (row < height)
                np.minimum.at(out, row[on_image] * width + col[on_image], z_color[inside][on_image])
    out[~np.isfinite(out)] = np.nan
    return out.reshape(height, width).astype(np.float32)
