"""The price of the bigger of two nested models: prismatic ⊂ revolute as r → ∞ (docs/selection.md).

A line is a circle of curvature κ = 0, so the two models differ in one
thing, the curvature vector κ (2,) of the path across its main direction
(magnitude 1/r, direction towards the centre). Both models are priced by
their marginal likelihood of the curvature the fit window shows,
κ̂ ~ N₂(κ, s²I), where s² is the estimate's variance plus the variance
σ_b² of a curvature the sensor adds to any path (a depth bias bends
straight slides; docs/selection.md §2). A depth error that grows with the
squared distance from the optical axis, δ = β·x²/z, bows a path crossing
the image at depth z with curvature 2β/z whatever its length, so σ_b is a
curvature (1/m), one per sensor:

    prismatic:  κ = 0                               → N₂(κ̂; 0, s²I)
    revolute:   κ = k·(cos θ, sin θ), θ ~ U(0, 2π),
                r = 1/k ~ U(r_min, r_max)           → ∫ N₂(κ̂; κ, s²I) p(κ) dκ

    log B = log p(κ̂ | revolute) − log p(κ̂ | prismatic)

The integral over θ is closed-form (a Bessel I₀), the one over k is a sum on
a grid. κ̂ and its variance come from a quadratic least-squares fit of the
two cross-track offsets against the along-track coordinate (the principal
axes of the window), after one pass that drops points more than
``outlier_k`` robust standard deviations off.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit
from scipy.special import i0e

from stslam.checks import check_fields, check_int, check_number


@dataclass(frozen=True)
class NestedPrice:
    """Prior of the revolute model's radius and the sensor's curvature noise (docs/selection.md).

    ``radius_min_m``, ``radius_max_m``: r ~ U(r_min, r_max) for a joint;
    ``bend_sigma_per_m``: σ_b of the curvature (1/m) a sensor's bias adds to
    a straight path; ``outlier_k``: points further than this many robust σ from
    the first quadratic fit are dropped; ``grid``: nodes of the k integral.
    """

    radius_min_m: float = 0.05
    radius_max_m: float = 1.2
    bend_sigma_per_m: float = 0.3
    outlier_k: float = 4.0
    grid: int = 256

    def __post_init__(self):
        check_fields(self, radius_min_m="(0, inf)", bend_sigma_per_m="[0, inf)", outlier_k="(0, inf)")
        # the radius prior U(r_min, r_max) needs r_max > r_min
        check_number("radius_max_m", self.radius_max_m, low=self.radius_min_m, low_open=True)
        check_int("grid", self.grid, low=8)


def curvature_estimate(points_world, sigma_m: float, outlier_k: float = 4.0) -> tuple[np.ndarray, float, float]:
    """Curvature vector κ̂ (2,) (1/m) of a window (n, 3), its standard deviation per component, along-track length L (m).

    The window's principal axis is the along-track coordinate x; each
    cross-track offset u is fitted as a + b·x + (κ/2)·x² by least squares, so
    κ̂ = 2c and var(κ̂) = 4σ²[(DᵀD)⁻¹]_cc with σ the larger of ``sigma_m`` and
    the residual's standard deviation. Raises ValueError for fewer than 5 points.
    """
    p = np.asarray(points_world, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 5:
        raise ValueError(f"need at least 5 points (n, 3), got shape {p.shape}")
    kappa, sd, length = _curvature_kernel(np.ascontiguousarray(p), float(sigma_m), float(outlier_k))
    return kappa, float(sd), float(length)


@njit(cache=True)
def _curvature_kernel(p, sigma_m, outlier_k):
    """:func:`curvature_estimate` of a window (n ≥ 5, 3), compiled (numba): the same steps as written there."""
    n_all = p.shape[0]
    centred = p.copy()
    for c in range(3):
        centred[:, c] -= np.sum(p[:, c]) / n_all
    _, _, vt = np.linalg.svd(centred, full_matrices=False)
    x = centred @ np.ascontiguousarray(vt[0])
    u = centred @ np.ascontiguousarray(vt[1:].T)  # (n, 2) cross-track offsets
    scale = max(np.max(np.abs(x)), 1e-9)
    xs_all = x / scale
    D_all = np.empty((n_all, 3))
    D_all[:, 0], D_all[:, 1], D_all[:, 2] = 1.0, xs_all, xs_all * xs_all
    keep = np.ones(n_all, dtype=np.bool_)
    D, coef, resid = D_all, np.zeros((3, 2)), u.copy()
    for _ in range(8):  # fit, drop outliers, refit until the inliers settle
        D = np.ascontiguousarray(D_all[keep])
        coef = np.linalg.lstsq(D, np.ascontiguousarray(u[keep]))[0]
        resid = u - D_all @ coef
        distance = np.sqrt(resid[:, 0] ** 2 + resid[:, 1] ** 2)
        robust = np.median(distance[keep]) / np.sqrt(2.0 * np.log(2.0))  # Rayleigh median → σ
        new_keep = distance <= outlier_k * max(robust, sigma_m)
        if new_keep.sum() < 5 or np.all(new_keep == keep):
            break
        keep = new_keep
    n = keep.sum()
    dof = max(n - 3, 1)
    kept = resid[keep]
    sigma = max(sigma_m, np.sqrt(np.sum(kept * kept) / (2 * dof)))
    cov = np.linalg.pinv(D.T @ D)
    kappa = 2.0 * coef[2] / scale ** 2
    x_kept = x[keep]
    length = np.max(x_kept) - np.min(x_kept)
    return kappa, 2.0 * sigma * np.sqrt(cov[2, 2]) / scale ** 2, length


def log_bayes_factor(kappa_hat, kappa_sigma: float, price: NestedPrice) -> float:
    """log p(κ̂ | revolute) − log p(κ̂ | prismatic) (module docstring), in nats."""
    k_hat = float(np.linalg.norm(kappa_hat))
    s2 = kappa_sigma ** 2 + price.bend_sigma_per_m ** 2
    k = _curvature_nodes(price.radius_min_m, price.radius_max_m, price.grid)
    # ∫ N₂(κ̂; k·e(θ), s²) dθ/2π = exp(−(k̂ − k)²/2s²) · i0e(k̂k/s²) / (2π s²)
    log_terms = -(k_hat - k) ** 2 / (2 * s2) + np.log(i0e(k_hat * k / s2))
    peak = float(np.max(log_terms))
    log_revolute = peak + float(np.log(np.mean(np.exp(log_terms - peak))))
    log_prismatic = -k_hat ** 2 / (2 * s2)
    return log_revolute - log_prismatic  # the common 1/(2π s²) cancels


@lru_cache(maxsize=16)
def _curvature_nodes(radius_min_m: float, radius_max_m: float, grid: int) -> np.ndarray:
    """k = 1/r at the midpoints of ``grid`` equal steps of r on [r_min, r_max] (read-only)."""
    radii = radius_min_m + (np.arange(grid) + 0.5) * (radius_max_m - radius_min_m) / grid
    k = 1.0 / radii
    k.flags.writeable = False
    return k


def window_log_bayes_factor(points_world, sigma_m: float, price: NestedPrice) -> float:
    """:func:`log_bayes_factor` of a fit window (n, 3); 0 (no evidence) for fewer than 5 points."""
    return window_price(points_world, sigma_m, price)[0]


def window_price(points_world, sigma_m: float, price: NestedPrice) -> tuple[float, float, float]:
    """(log B, |κ̂|, σ of κ̂'s components) of a fit window (n, 3); (0, 0, inf) for fewer than 5 points."""
    if np.asarray(points_world).shape[0] < 5:
        return 0.0, 0.0, np.inf
    kappa, sd, _ = curvature_estimate(points_world, sigma_m, price.outlier_k)
    return log_bayes_factor(kappa, sd, price), float(np.linalg.norm(kappa)), sd


class WindowPrice:
    """log B of the latest fit window given to :meth:`refit`, computed when first read (only decisions read it).

    ``curvature`` holds (|κ̂|, σ) of that window once computed, ``previous`` those of the window before.
    """

    def __init__(self, sigma_m: float, price: NestedPrice):
        self.sigma_m, self.price = float(sigma_m), price
        self._window, self._log_b = None, None
        self.curvature = self.previous = None

    def refit(self, window: np.ndarray) -> None:
        """A new fit window (n, 3), to be priced when next read."""
        self._window = window

    @property
    def log_bayes_factor(self) -> float | None:
        """log B (revolute : prismatic) of the latest window; None before the first."""
        if self._window is not None:
            self._log_b, *curvature = window_price(self._window, self.sigma_m, self.price)
            self.previous, self.curvature, self._window = self.curvature, tuple(curvature), None
        return self._log_b

    def quiet(self) -> bool:
        """Whether the latest window's |κ̂| is within its σ of the previous window's (the curvature has settled)."""
        self.log_bayes_factor  # noqa: B018 - price the latest window
        return self.previous is not None and abs(self.curvature[0] - self.previous[0]) < self.curvature[1]
