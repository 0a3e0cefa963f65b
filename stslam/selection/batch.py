"""Batch model selection: robust fits to the whole track, chosen by BIC (docs/selection.md §3).

The way articulation was classified before online filters (e.g. Sturm et al.,
JAIR 2011): fit every model to all of a track's points and keep the one of
smallest Bayesian information criterion. Each point's likelihood is a
mixture of the model and a uniform outlier density over the track's
bounding box (volume V; MLESAC, Torr & Zisserman 2000, with γ = ``inlier_fraction``; hypotheses
ranked by MSAC's truncated cost):

    static:     γ·N₃(d; σ)            + (1 − γ)/V
    prismatic:  γ·N₂(d_⊥; σ)/L        + (1 − γ)/V     (uniform along the L metres travelled)
    revolute:   γ·N₂(d_⊥; σ)/(r·Δφ)   + (1 − γ)/V     (uniform along the arc swept)

with d the 3D distance to the point, d_⊥ the distance across the line or
circle. Hypotheses come from minimal samples (1 point, 2 for a line, 3 for a
circle); the best is refined by the least-squares fit (SPEC 2) on its
inliers (d < ``inlier_k``·σ). Then

    BIC_M = −2 Σ log p_i + k_M·ln n,   k = 3 (point), 4 + 2 (line and its ends), 6 + 2 (circle and its ends)

σ is the larger of ``sigma_m`` and the circle's robust residual scale, so
one noise level serves all three models. Points are first thinned to
``spacing_m`` so a long rest does not count as hundreds of observations.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stslam.articulation.models import get_model
from stslam.errors import DegenerateFitError

MODEL_DOF = {"static": 3, "prismatic": 6, "revolute": 8}


@dataclass(frozen=True)
class BatchSettings:
    """``sigma_m``: noise floor (m); ``inlier_k``: inlier bound (σ); ``inlier_fraction``: γ;
    ``iterations`` per model; ``spacing_m``: thinning; ``seed``."""

    sigma_m: float = 0.002
    inlier_fraction: float = 0.95
    inlier_k: float = 3.0
    iterations: int = 100
    spacing_m: float = 0.005
    seed: int = 0


@dataclass(frozen=True)
class BatchResult:
    """The chosen model, each model's BIC and robust structure (None where no fit exists), σ used."""

    model: str
    bic: dict
    structures: dict
    sigma_m: float


def thin(points, spacing_m: float) -> np.ndarray:
    """Points kept when each must be ``spacing_m`` from the previous kept one (the first is kept)."""
    p = np.asarray(points, dtype=float)
    kept = [p[0]]
    for z in p[1:]:
        if np.linalg.norm(z - kept[-1]) >= spacing_m:
            kept.append(z)
    return np.array(kept)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """np.cross of two 3-vectors: the same products and differences, without its axis handling."""
    (a0, a1, a2), (b0, b1, b2) = a.tolist(), b.tolist()
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])


def circle_through(p1, p2, p3):
    """Centre (3,), unit normal (3,) and radius of the circle through three points; None if collinear."""
    a, b = p2 - p1, p3 - p1
    n = _cross(a, b)
    nn = float(n @ n)
    if nn < 1e-18:
        return None
    centre = p1 + _cross(a @ a * b - b @ b * a, n) / (2.0 * nn)  # circumcentre
    return centre, n / np.sqrt(nn), float(np.linalg.norm(p1 - centre))


def distances(name: str, points: np.ndarray, structure) -> np.ndarray:
    """3D distance (n,) of each point to a structure: ("point", c), ("line", p0, u) or ("circle", c, n, r)."""
    if name == "static":
        return np.linalg.norm(points - structure[0], axis=1)
    if name == "prismatic":
        p0, u = structure
        d = points - p0
        return np.linalg.norm(d - np.outer(d @ u, u), axis=1)
    centre, normal, radius = structure
    d = points - centre
    h = d @ normal
    radial = np.linalg.norm(d - np.outer(h, normal), axis=1) - radius
    return np.sqrt(h * h + radial * radial)


def _stacked_distances(name: str, points: np.ndarray, structures) -> np.ndarray:
    """:func:`distances` (H, n) of H structures of one model, as one array operation per step of it (same numbers)."""
    parts = [np.array(part) for part in zip(*structures)]
    if name == "static":
        return np.linalg.norm(points[None] - parts[0][:, None, :], axis=2)
    if name == "prismatic":
        p0, u = parts
        d = points[None] - p0[:, None, :]
        return np.linalg.norm(d - (d @ u[:, :, None]) * u[:, None, :], axis=2)
    centre, normal, radius = parts
    d = points[None] - centre[:, None, :]
    h = d @ normal[:, :, None]
    radial = np.linalg.norm(d - h * normal[:, None, :], axis=2) - radius[:, None]
    h = h[:, :, 0]
    return np.sqrt(h * h + radial * radial)


def _hypothesis(name: str, sample: np.ndarray):
    if name == "static":
        return (sample[0],)
    if name == "prismatic":
        u = sample[1] - sample[0]
        norm = np.linalg.norm(u)
        return None if norm < 1e-12 else (sample[0], u / norm)
    return circle_through(*sample[:3])


def _refined(name: str, inliers: np.ndarray):
    """The least-squares structure (SPEC 2) of the inliers, in the tuple form of :func:`distances`."""
    fit = get_model(name).fit(inliers)
    if name == "static":
        return (fit.p0,)
    if name == "prismatic":
        return (fit.p0, fit.direction)
    return (fit.centre_world, fit.normal, fit.radius)


def _extent(name: str, points: np.ndarray, structure, sigma_m: float) -> float:
    """Length (m) the inliers cover along the line or the arc, plus 2σ."""
    if name == "prismatic":
        t = (points - structure[0]) @ structure[1]
        return float(np.ptp(t)) + 2 * sigma_m if t.size else 2 * sigma_m
    centre, normal, radius = structure
    d = points - centre
    e1 = d[0] - (d[0] @ normal) * normal if d.shape[0] else np.cross(normal, [1.0, 0.0, 0.0])
    e1 /= max(np.linalg.norm(e1), 1e-12)
    phi = np.sort(np.arctan2(d @ np.cross(normal, e1), d @ e1))
    gaps = np.diff(np.concatenate([phi, phi[:1] + 2 * np.pi])) if phi.size else np.array([2 * np.pi])
    return radius * (2 * np.pi - float(np.max(gaps))) + 2 * sigma_m


def negative_log_likelihood(name: str, points: np.ndarray, structure, sigma_m: float, settings: BatchSettings,
                            log_volume: float) -> float:
    """−Σ log p_i of the mixture in the module docstring."""
    d = distances(name, points, structure)
    dims = 3 if name == "static" else 2
    log_model = -0.5 * (d / sigma_m) ** 2 - dims * 0.5 * np.log(2 * np.pi * sigma_m ** 2)
    if name != "static":
        log_model = log_model - np.log(_extent(name, points[d < settings.inlier_k * sigma_m], structure, sigma_m))
    g = settings.inlier_fraction
    return float(-np.sum(np.logaddexp(np.log(g) + log_model, np.log(1 - g) - log_volume)))


def robust_fit(name: str, points: np.ndarray, sigma_m: float, settings: BatchSettings, rng):
    """Robust fit of one model: (structure tuple or None, −Σ log p_i).

    Hypotheses are ranked by the truncated quadratic cost Σ min(d²/σ², k²)
    (MSAC, cheap); the best and its refinement are scored by the mixture.
    """
    size = {"static": 1, "prismatic": 2, "revolute": 3}[name]
    n = points.shape[0]
    box = np.ptp(points, axis=0) + 6 * sigma_m
    log_volume = float(np.sum(np.log(box)))
    best, best_rank = None, np.inf
    cap = settings.inlier_k ** 2
    samples = [rng.choice(n, size, replace=False) for _ in range(settings.iterations if n > size else 0)]
    hypotheses = [h for h in (_hypothesis(name, points[i]) for i in samples) if h is not None]
    if hypotheses:
        ranks = np.sum(np.minimum((_stacked_distances(name, points, hypotheses) / sigma_m) ** 2, cap), axis=1)
        for structure, rank in zip(hypotheses, ranks.tolist()):
            if rank < best_rank:
                best, best_rank = structure, rank
    if best is None:
        return None, np.inf
    best_cost = negative_log_likelihood(name, points, best, sigma_m, settings, log_volume)
    inliers = points[distances(name, points, best) < settings.inlier_k * sigma_m]
    try:
        refined = _refined(name, inliers) if inliers.shape[0] > size + 1 else best
    except DegenerateFitError:
        refined = best
    cost = negative_log_likelihood(name, points, refined, sigma_m, settings, log_volume)
    return (refined, cost) if cost < best_cost else (best, best_cost)


def batch_select(points_world, settings: BatchSettings, models=("static", "prismatic", "revolute")) -> BatchResult:
    """Fit every model robustly to the whole (thinned) track and choose by BIC (module docstring)."""
    points = np.asarray(points_world, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3 or points.shape[0] < 3 or not np.all(np.isfinite(points)):
        raise ValueError(f"points_world must be at least 3 finite points (n, 3), got shape {points.shape}")
    window = thin(points, settings.spacing_m)
    if window.shape[0] < 5:
        window = points
    n = window.shape[0]
    rng = np.random.default_rng(settings.seed)
    sigma = settings.sigma_m
    if "revolute" in models:  # the noise scale: the circle's robust residual (MAD), never below sigma_m
        circle, _ = robust_fit("revolute", window, sigma, settings, rng)
        if circle is not None:
            d = distances("revolute", window, circle)
            sigma = max(sigma, float(np.median(d)) / np.sqrt(2.0 * np.log(2.0)))  # Rayleigh median
    bic, structures = {}, {}
    for name in models:
        structure, cost = robust_fit(name, window, sigma, settings, rng)
        structures[name] = structure
        bic[name] = 2 * cost + MODEL_DOF[name] * np.log(n)
    return BatchResult(model=min(bic, key=bic.get), bic=bic, structures=structures, sigma_m=sigma)
