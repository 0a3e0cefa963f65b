"""Batch evidence of a point track's kept window for the two moving models (SPEC 4, 13, 18).

Online selection scores one-step predictions; a door seen mostly at rest gives
two clusters of positions that a line predicts about as well as an arc, and its
early decision can be wrong. This module scores the whole kept window at once:
each model's structure is fitted to the window (SPEC 2.2, 2.3) and the window's
χ² about it, each point weighted by its own variance, gives a BIC

    BIC_M = χ²_M + k_M log n,     k_prismatic = 4 (a line), k_revolute = 6 (plane, centre, radius),

the motion variable of each observation being free under both (it cancels). The
revolute : prismatic log-odds of one track is −(BIC_r − BIC_p)/2; a body's
points share one joint (SPEC 13), so their log-odds add (SPEC 18: sharing the
model across a body's points took the kitchen's movers from 90.9% to 95.5% with
the true poses).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2

from stslam.articulation.models import get_model
from stslam.errors import DegenerateFitError

__all__ = ["CIRCLE_PARAMETERS", "LINE_PARAMETERS", "MIN_WINDOW", "rest_means", "revolute_log_odds", "turn_log_odds",
           "window_fit"]

LINE_PARAMETERS = 4  # a 3D line: a point in a plane across it (2) and a direction (2)
CIRCLE_PARAMETERS = 6  # a circle in 3D: the plane (3), the centre in it (2), the radius (1)
REST_SPREAD = 3.0  # an observation farther than this many stds from its run's mean ends the run
TURN_ALPHA = 1e-3  # a pair's difference moving at this significance has turned
QUIET_PAIR_M = 0.15  # a pair this far apart whose difference stays put leans towards a slide
QUIET_WEIGHT = 1.0  # ... by this much (nats): a pair along a hinge is quiet too
TURN_CAP = 6.0  # log-odds one pair of a body adds (nats): it outweighs one point's curvature
MIN_WINDOW = 5  # fewest distinct points for a window's evidence (a circle needs 3, a BIC a few more)


def _distances(name: str, structure, points: np.ndarray) -> np.ndarray:
    """Squared distance of each point to the fitted line or circle (m²): SPEC 2.2, 2.3."""
    d = points - structure.p0
    if name == "prismatic":
        along = d @ structure.direction
        return np.sum(d * d, axis=1) - along ** 2
    x, y = d @ structure.v1, d @ structure.v2
    height = d @ structure.normal
    radial = np.hypot(x - structure.centre_xy[0], y - structure.centre_xy[1]) - structure.radius
    return height ** 2 + radial ** 2


def window_fit(name: str, points, variances):
    """(structure, χ²) of model ``name`` fitted to the window ``points`` (n, 3) with per-point
    variances (n,) (m², each axis); (None, inf) when the window cannot carry it (SPEC 2.4)."""
    points = np.asarray(points, dtype=float)
    try:
        structure = get_model(name).fit(points)
    except DegenerateFitError:
        return None, math.inf
    return structure, float(np.sum(np.maximum(_distances(name, structure, points), 0.0) / variances))


def rest_means(points, variances, spread: float = REST_SPREAD) -> tuple[np.ndarray, np.ndarray]:
    """The window with each run of observations at rest replaced by its mean (its sufficient statistic).

    In time order, an observation joins the current run while it lies within ``spread`` standard
    deviations (per axis, its own) of the run's mean; a run of n weighs as one point of variance
    (Σ 1/v)⁻¹. A door seen mostly at rest is then two or three well-placed means and the points
    of its swings: a circle can no longer buy its fit by bending through the noise of a cluster
    (SPEC 18's "two clusters of positions are a line as well as an arc").
    """
    points = np.asarray(points, dtype=float)
    variances = np.broadcast_to(np.asarray(variances, dtype=float), (points.shape[0],))
    means, weights = [], []
    total, weight = np.zeros(3), 0.0
    for p, v in zip(points, variances):
        if weight > 0.0:
            mean = total / weight
            if np.sum((p - mean) ** 2) > spread ** 2 * v:
                means.append(mean)
                weights.append(weight)
                total, weight = np.zeros(3), 0.0
        total, weight = total + p / v, weight + 1.0 / v
    means.append(total / weight)
    weights.append(weight)
    return np.array(means), 1.0 / np.array(weights)


def revolute_log_odds(points, variances) -> float:
    """log p(revolute | window) − log p(prismatic | window) by BIC (module docstring) on the window's
    rests and motion (:func:`rest_means`); 0 when that leaves too little to say (fewer than
    ``MIN_WINDOW`` points)."""
    points, variances = rest_means(points, variances)
    n = points.shape[0]
    if n < MIN_WINDOW:
        return 0.0
    _, chi2_line = window_fit("prismatic", points, variances)
    _, chi2_circle = window_fit("revolute", points, variances)
    if not math.isfinite(chi2_circle):
        return -math.inf if math.isfinite(chi2_line) else 0.0
    if not math.isfinite(chi2_line):
        return math.inf
    # SPEC 18: BIC difference, halved to a log-odds; the motion variables cancel.
    return 0.5 * (chi2_line - chi2_circle) - 0.5 * (CIRCLE_PARAMETERS - LINE_PARAMETERS) * math.log(n)


def turn_log_odds(points_a, points_b, covs_a, covs_b, cap: float = TURN_CAP) -> float:
    """Revolute : prismatic log-odds from two points of one rigid body seen at the same frames (SPEC 13, 18).

    A slide moves a body's points alike, so their difference d_t = p_a,t − p_b,t stays
    constant; a turn by φ about a hinge along u moves it by (R(u, φ) − I) d, which vanishes
    only for a pair along the hinge. The χ² of d_t about its weighted mean (covariances
    Σ_a + Σ_b; a pose error shared by the frame's points cancels) is χ²(3(n − 1)) under a
    slide. A significant χ² (p < ``TURN_ALPHA``) says the body turned: +``cap``. A quiet χ²
    for a pair at least ``QUIET_PAIR_M`` apart is weak evidence of a slide, −``QUIET_WEIGHT``
    (the pair might lie along the hinge); a closer pair says nothing.
    """
    a = np.asarray(points_a, dtype=float).reshape(-1, 3)
    b = np.asarray(points_b, dtype=float).reshape(-1, 3)
    n = a.shape[0]
    if n < MIN_WINDOW:
        return 0.0
    d = a - b
    info = np.linalg.inv(np.asarray(covs_a, dtype=float) + np.asarray(covs_b, dtype=float))
    mean = np.linalg.solve(info.sum(axis=0), np.einsum("nij,nj->i", info, d))
    r = d - mean
    statistic = float(np.einsum("ni,nij,nj->", r, info, r))
    if chi2.sf(statistic, 3 * (n - 1)) < TURN_ALPHA:
        return cap
    return -QUIET_WEIGHT if np.linalg.norm(mean) >= QUIET_PAIR_M else 0.0
