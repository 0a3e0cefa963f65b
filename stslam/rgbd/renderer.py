"""Render RGB-D views of textured planar quads, and the depth sensor's noise and holes (SPEC 9).

No GPU and no OpenGL: each quad is drawn by warping its texture into the image
with the plane-induced homography (``cv2.warpPerspective``), and a z-buffer is
kept from the plane's inverse depth, which is affine in pixel coordinates.
Camera conventions are those of :mod:`stslam.robot.pinhole`.

For a plane n·X = δ in the camera frame (n unit, δ < 0 when the camera sees
its front side), the point seen at pixel p = (u, v, 1)ᵀ is X = z K⁻¹ p, so
    1/z = (K⁻ᵀ n)·p / δ        (affine in u and v),
and the cosine of the incidence angle between the ray and the normal is
    cos ι = |n·K⁻¹p| / |K⁻¹p| = |δ| (1/z) / |K⁻¹p|.
A texel (s, t) of a level of size (rows, cols) sits at
    X = P0 + ((s + ½)/cols) E_u + ((t + ½)/rows) E_v,
so the texture-to-image homography is H = K [R E_u/cols, R E_v/rows, R(P0 + E_u/2cols + E_v/2rows) + t]
with (R, t) = T_camera_world. Textures are mip-mapped (``cv2.pyrDown``) and the
level is chosen per quad from its texel density at its depth, which keeps
distant surfaces from aliasing into spurious corners.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stslam.geometry import invert_pose

NEAR_M = 0.05  # near clipping plane (m)


@dataclass(frozen=True)
class PinholeImage:
    """A pinhole camera and its image grid.

    Attributes
    ----------
    K : numpy.ndarray, shape (3, 3)
        Intrinsics (pixels).
    width, height : int
        Image size (pixels).
    ray_norm : numpy.ndarray, shape (height, width), float32
        |K⁻¹ (u, v, 1)ᵀ| per pixel, to turn inverse depth into incidence.
    """

    K: np.ndarray
    width: int
    height: int
    ray_norm: np.ndarray

    @classmethod
    def from_intrinsics(cls, K, width: int, height: int) -> "PinholeImage":
        K = np.asarray(K, dtype=float)
        u = (np.arange(width) - K[0, 2]) / K[0, 0]
        v = (np.arange(height) - K[1, 2]) / K[1, 1]
        norm = np.sqrt(1.0 + u[None, :] ** 2 + v[:, None] ** 2).astype(np.float32)
        return cls(K=K, width=int(width), height=int(height), ray_norm=norm)


@dataclass
class RenderedView:
    """Noise-free render of one view.

    Attributes
    ----------
    rgb : numpy.ndarray, shape (H, W, 3), uint8
    depth_m : numpy.ndarray, shape (H, W), float32
        Optical-axis depth z (m); +inf where nothing was drawn.
    label : numpy.ndarray, shape (H, W), uint8
        Surface label of each pixel (``stslam.rgbd.scene.LABEL_*``; 0 = nothing).
    cos_incidence : numpy.ndarray, shape (H, W), float32
        Cosine of the angle between each pixel's ray and the surface normal.
    """

    rgb: np.ndarray
    depth_m: np.ndarray
    label: np.ndarray
    cos_incidence: np.ndarray


def texture_pyramid(texture_rgb: np.ndarray, min_size: int = 4) -> list[np.ndarray]:
    """Mip-map levels of an RGB texture as RGBA uint8 (alpha 255): level k has 2⁻ᵏ the resolution."""
    rgba = cv2.cvtColor(np.ascontiguousarray(texture_rgb, dtype=np.uint8), cv2.COLOR_RGB2RGBA)
    levels = [rgba]
    while min(levels[-1].shape[:2]) >= 2 * min_size:
        levels.append(cv2.pyrDown(levels[-1]))
    return levels


def _clip_polygon_near(points_camera: np.ndarray, near: float) -> np.ndarray:
    """Part of a convex polygon (n, 3) with z ≥ ``near`` (Sutherland–Hodgman against one plane)."""
    out = []
    n = len(points_camera)
    for i in range(n):
        a, b = points_camera[i], points_camera[(i + 1) % n]
        a_in, b_in = a[2] >= near, b[2] >= near
        if a_in:
            out.append(a)
        if a_in != b_in:
            s = (near - a[2]) / (b[2] - a[2])
            out.append(a + s * (b - a))
    return np.array(out).reshape(-1, 3)


def render_view(quads, pyramids, camera: PinholeImage, T_world_camera, near_m: float = NEAR_M) -> RenderedView:
    """Render quads seen by ``camera`` at pose ``T_world_camera`` (SPEC 9).

    Parameters
    ----------
    quads : sequence of stslam.rgbd.scene.TexturedQuad
        Surfaces in the world frame.
    pyramids : sequence of list of numpy.ndarray
        Mip-map levels (:func:`texture_pyramid`) per texture index.
    camera : PinholeImage
    T_world_camera : array_like, shape (4, 4)
        Pose of the camera optical frame in the world frame.

    Returns
    -------
    RenderedView
    """
    W, H, K = camera.width, camera.height, camera.K
    T_cw = invert_pose(T_world_camera)
    R, t = T_cw[:3, :3], T_cw[:3, 3]
    K_inv_T = np.linalg.inv(K).T
    f_mean = 0.5 * (K[0, 0] + K[1, 1])
    us = np.arange(W, dtype=np.float32)
    vs = np.arange(H, dtype=np.float32)

    rgb = np.zeros((H, W, 3), np.uint8)
    inv_depth = np.zeros((H, W), np.float32)  # 0 = infinitely far
    delta_abs = np.zeros((H, W), np.float32)
    label = np.zeros((H, W), np.uint8)

    for quad in quads:
        n_c = R @ quad.normal_world
        p0_c = R @ quad.corner_world + t
        delta = float(n_c @ p0_c)
        if delta > -1e-9:  # back side faces the camera, or seen edge-on
            continue
        eu_c, ev_c = R @ quad.edge_u_world, R @ quad.edge_v_world
        corners = np.array([p0_c, p0_c + eu_c, p0_c + eu_c + ev_c, p0_c + ev_c])
        visible = _clip_polygon_near(corners, near_m)
        if len(visible) < 3:
            continue
        uv = (visible @ K.T)[:, :2] / visible[:, 2:3]
        x0, y0 = max(0, int(np.floor(uv[:, 0].min())) - 1), max(0, int(np.floor(uv[:, 1].min())) - 1)
        x1, y1 = min(W, int(np.ceil(uv[:, 0].max())) + 2), min(H, int(np.ceil(uv[:, 1].max())) + 2)
        if x1 <= x0 or y1 <= y0:
            continue

        # Mip level: texels per pixel = texels per metre · z / f, at a representative depth.
        levels = pyramids[quad.texture]
        rows0, cols0 = levels[0].shape[:2]
        texels_per_m = np.sqrt(rows0 * cols0 / (np.linalg.norm(eu_c) * np.linalg.norm(ev_c)))
        z_ref = np.sqrt(visible[:, 2].min() * visible[:, 2].max())
        level = int(np.clip(np.floor(np.log2(max(1.0, texels_per_m * z_ref / f_mean))), 0, len(levels) - 1))
        texture = levels[level]
        if quad.shade != 1.0:
            texture = cv2.multiply(texture, (quad.shade, quad.shade, quad.shade, 1.0))
        rows, cols = texture.shape[:2]

        # Texture-to-image homography, shifted to the bounding box.
        H_img_tex = K @ np.column_stack([eu_c / cols, ev_c / rows, p0_c + 0.5 * eu_c / cols + 0.5 * ev_c / rows])
        shift = np.array([[1.0, 0.0, -x0], [0.0, 1.0, -y0], [0.0, 0.0, 1.0]])
        warped = cv2.warpPerspective(texture, shift @ H_img_tex, (x1 - x0, y1 - y0), flags=cv2.INTER_LINEAR,
                                     borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0))

        # 1/z = (K⁻ᵀ n)·p / δ over the box.
        g = (K_inv_T @ n_c) / delta
        w = (np.float32(g[0]) * us[x0:x1])[None, :] + (np.float32(g[1]) * vs[y0:y1] + np.float32(g[2]))[:, None]
        alpha = warped[..., 3]
        win = (alpha >= 128) & (w > inv_depth[y0:y1, x0:x1])
        if not win.any():
            continue
        colour = warped[..., :3]
        rim = win & (alpha < 255)
        if rim.any():  # texels blended with the transparent border: undo the darkening
            colour = colour.copy()
            colour[rim] = np.clip(colour[rim] * (255.0 / alpha[rim])[:, None], 0, 255).astype(np.uint8)
        np.copyto(rgb[y0:y1, x0:x1], colour, where=win[..., None])
        np.copyto(inv_depth[y0:y1, x0:x1], w, where=win)
        delta_abs[y0:y1, x0:x1][win] = -delta
        label[y0:y1, x0:x1][win] = quad.label

    with np.errstate(divide="ignore"):
        depth = np.where(inv_depth > 0, 1.0 / inv_depth, np.inf).astype(np.float32)
    cos_incidence = np.clip(delta_abs * inv_depth / camera.ray_norm, 0.0, 1.0).astype(np.float32)
    return RenderedView(rgb=rgb, depth_m=depth, label=label, cos_incidence=cos_incidence)


def sensor_depth(depth_m, cos_incidence, rng: np.random.Generator, *, noise_coefficient: float = 1.5e-3,
                 min_range_m: float = 0.3, max_range_m: float = 4.0,
                 max_incidence_deg: float = 75.0) -> np.ndarray:
    """Depth image as the sensor reports it: noisy, with holes as NaN (SPEC 9).

    z_meas = z + σ_z(z)·ε, ε ~ N(0, 1) per pixel, σ_z = c·z². A pixel is a hole
    (NaN) where the true depth is outside [min_range_m, max_range_m] or the ray
    meets the surface at more than ``max_incidence_deg`` from its normal
    (grazing angles return no structured-light pattern).

    Parameters
    ----------
    depth_m : numpy.ndarray, shape (H, W)
        True depth (m), +inf where nothing.
    cos_incidence : numpy.ndarray, shape (H, W)
    rng : numpy.random.Generator
        Draws H·W standard normals.

    Returns
    -------
    numpy.ndarray, shape (H, W), float32
    """
    z = np.asarray(depth_m, dtype=np.float32)
    eps = rng.standard_normal(z.shape, dtype=np.float32)
    finite = np.isfinite(z)
    z_safe = np.where(finite, z, 0.0).astype(np.float32)
    # σ_z·ε, σ_z = c·z² as stslam.geometry.depth_noise_std, evaluated in float32 as ((c·z)·z)·ε:
    # the generated sequences carry this rounding.
    noisy = z_safe + np.float32(noise_coefficient) * z_safe * z_safe * eps
    hole = (~finite) | (z_safe < min_range_m) | (z_safe > max_range_m)
    hole |= np.asarray(cos_incidence) < np.cos(np.deg2rad(max_incidence_deg))
    noisy[hole] = np.nan
    return noisy


def sensor_rgb(rgb, rng: np.random.Generator, noise_std: float) -> np.ndarray:
    """RGB with additive Gaussian pixel noise of ``noise_std`` grey levels, rounded and clipped (uint8)."""
    if noise_std <= 0:
        return np.asarray(rgb, dtype=np.uint8).copy()
    noise = rng.standard_normal(np.shape(rgb), dtype=np.float32) * np.float32(noise_std)
    return np.clip(np.rint(np.asarray(rgb, np.float32) + noise), 0, 255).astype(np.uint8)
