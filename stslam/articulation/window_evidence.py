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
from typing import NamedTuple

import numpy as np
from scipy.special import chdtrc

from stslam.articulation.models import get_model
from stslam.articulation.small_lm import WEIGHTED_CIRCLE_3D, levenberg_marquardt
from stslam.articulation.window_kernels import rest_runs, swept_angle, turn_score, turn_statistic
from stslam.errors import DegenerateFitError
from stslam.geometry import cross3

__all__ = ["CIRCLE_PARAMETERS", "LINE_PARAMETERS", "MIN_WINDOW", "PairTurn", "quiet_log_odds", "rest_means",
           "revolute_log_odds", "turn_evidence", "turn_log_odds", "window_fit"]

LINE_PARAMETERS = 4  # a 3D line: a point in a plane across it (2) and a direction (2)
CIRCLE_PARAMETERS = 6  # a circle in 3D: the plane (3), the centre in it (2), the radius (1)
REST_SPREAD = 3.0  # an observation farther than this many stds from its run's mean ends the run
TURN_ALPHA = 1e-3  # a pair's difference moving at this significance has turned (shared by the two tests)
REFERENCE_FRAMES = 5  # a pair's first frames whose mean midpoint is where its part started (turn_score)
QUIET_PAIR_M = 0.15  # a pair this far apart whose difference stays put leans towards a slide
QUIET_WEIGHT = 1.0  # ... by this much (nats), once quiet pairs point along two directions (quiet_log_odds)
QUIET_SPREAD_DEG = 30.0  # quiet pairs all within this angle of one line could all lie along one hinge
TURN_CAP = 6.0  # log-odds one pair of a body adds (nats): it outweighs one point's curvature
REFINE_EVALUATIONS = 40  # residual evaluations of the weighted refinement (the Jacobian is analytic):
                         # it starts at the unweighted geometric fit, a few steps away
TOLERANCE = 1e-8  # relative tolerances (as MINPACK's) on the cost, the step and the gradient's angle
MAX_SWEEP_RAD = 2.6  # a hinge turns furniture by less than 150°: a wider arc is noise bent into a circle
MIN_WINDOW = 5  # fewest distinct points for a window's evidence (a circle needs 3, a BIC a few more)


def _line_chi2(points: np.ndarray, weights: np.ndarray) -> float:
    """χ² of the weighted total-least-squares line (SPEC 2.2 with a weight per point): the weighted mean
    and the leading eigenvector of the weighted scatter, which minimise Σ w |p⊥|² exactly."""
    mean = weights @ points / weights.sum()
    d = points - mean
    _, vectors = np.linalg.eigh((d * weights[:, None]).T @ d)
    along = d @ vectors[:, -1]
    return float(weights @ np.maximum(np.sum(d * d, axis=1) - along ** 2, 0.0))


def _circle_chi2(points: np.ndarray, weights: np.ndarray) -> float:
    """χ² of the weighted geometric circle fit (SPEC 2.3 with a weight per point): the model's own fit,
    then refined with each point's weight (a rest's mean weighs as the n observations it stands for);
    inf when the window carries no circle (SPEC 2.4). The refinement is Levenberg–Marquardt with the
    analytic Jacobian (:mod:`stslam.articulation.small_lm`, residual kind ``WEIGHTED_CIRCLE_3D``: the
    centre, the normal tilted along the fit's v1, v2, the radius), at most ``REFINE_EVALUATIONS``
    residual evaluations."""
    try:
        start = get_model("revolute").fit(points)
    except DegenerateFitError:
        return math.inf
    x0 = np.concatenate([start.centre_world, [0.0, 0.0, start.radius]])
    basis = np.stack([start.v1, start.v2, cross3(start.v1, start.v2)])
    x, residuals, _ = levenberg_marquardt(WEIGHTED_CIRCLE_3D, x0, np.ascontiguousarray(points), np.sqrt(weights),
                                          basis, TOLERANCE, TOLERANCE, TOLERANCE, REFINE_EVALUATIONS)
    if swept_angle(x, np.ascontiguousarray(points), basis) > MAX_SWEEP_RAD:  # compiled (window_kernels)
        return math.inf  # a small circle bent through the noise of a line, not a hinge
    return float(residuals @ residuals)


def window_fit(name: str, points):
    """Model ``name``'s structure fitted to the window ``points`` (n, 3) (SPEC 2.2, 2.3); None when the
    window cannot carry it (SPEC 2.4)."""
    try:
        return get_model(name).fit(np.asarray(points, dtype=float))
    except DegenerateFitError:
        return None


def rest_means(points, variances, spread: float = REST_SPREAD) -> tuple[np.ndarray, np.ndarray]:
    """The window with each run of observations at rest replaced by its mean (its sufficient statistic).

    In time order, an observation joins the current run while it lies within ``spread`` standard
    deviations (per axis, its own) of the run's mean; a run of n weighs as one point of variance
    (Σ 1/v)⁻¹. A door seen mostly at rest is then two or three well-placed means and the points
    of its swings: a circle can no longer buy its fit by bending through the noise of a cluster
    (SPEC 18's "two clusters of positions are a line as well as an arc").
    """
    points = np.ascontiguousarray(points, dtype=float).reshape(-1, 3)
    if points.shape[0] == 0:
        raise ValueError("rest_means: an empty window has no rests")
    variances = np.ascontiguousarray(np.broadcast_to(np.asarray(variances, dtype=float), (points.shape[0],)))
    means, weights = rest_runs(points, variances, spread ** 2)  # compiled (window_kernels)
    return means, 1.0 / weights


def revolute_log_odds(points, variances) -> float:
    """log p(revolute | window) − log p(prismatic | window) by BIC (module docstring) on the window's
    rests and motion (:func:`rest_means`); 0 when that leaves too little to say (fewer than
    ``MIN_WINDOW`` points)."""
    points, variances = rest_means(points, variances)
    n = points.shape[0]
    if n < MIN_WINDOW:
        return 0.0
    weights = 1.0 / variances
    chi2_line, chi2_circle = _line_chi2(points, weights), _circle_chi2(points, weights)
    if not math.isfinite(chi2_circle):  # no circle, or none a hinge makes: the line's fit, the line's price
        chi2_circle = chi2_line
    # SPEC 18: BIC difference, halved to a log-odds; the motion variables cancel.
    return 0.5 * (chi2_line - chi2_circle) - 0.5 * (CIRCLE_PARAMETERS - LINE_PARAMETERS) * math.log(n)


class PairTurn(NamedTuple):
    """What two points of one body say about a turn: the log-odds of :func:`turn_evidence` and the
    pair's weighted mean difference p_a − p_b (3,) (m)."""

    log_odds: float
    offset: np.ndarray


def turn_evidence(points_a, points_b, covs_a, covs_b, cap: float = TURN_CAP) -> PairTurn:
    """Revolute : prismatic log-odds from two points of one rigid body seen at the same frames (SPEC 13, 18).

    A slide moves a body's points alike, so their difference d_t = p_a,t − p_b,t stays
    constant; a turn by φ about a hinge along u moves it by (R(u, φ) − I) d, which vanishes
    only for a pair along the hinge. The χ² of d_t about its weighted mean (covariances
    Σ_a + Σ_b; a pose error shared by the frame's points cancels) is χ²(3(n − 1)) under a
    slide; it spreads its power over every frame. A second test looks where a turn shows: d's change
    along with how far the pair has moved (a score with 3 dof, :func:`~stslam.articulation.window_kernels.turn_score`),
    which finds a door whose pair lies almost along the hinge (the kitchen's wall cabinet: 5 cm across
    it, turned by 0.9 rad: p ≈ 1e-7 and 5e-5 on two seeds, where the first test stayed quiet). Either significant
    (p < ``TURN_ALPHA``/2 each, Bonferroni) says the body turned: +``cap``. A quiet χ²
    for a pair at least ``QUIET_PAIR_M`` apart is weak evidence of a slide, −``QUIET_WEIGHT``,
    but only together with quiet pairs along another direction (:func:`quiet_log_odds`): the
    pair might lie along the hinge. A closer pair says nothing.
    """
    a = np.asarray(points_a, dtype=float).reshape(-1, 3)
    b = np.asarray(points_b, dtype=float).reshape(-1, 3)
    n = a.shape[0]
    if n < MIN_WINDOW:
        return PairTurn(0.0, np.zeros(3))
    covs = (np.asarray(covs_a, dtype=float).reshape(n, 3, 3), np.asarray(covs_b, dtype=float).reshape(n, 3, 3))
    ok, statistic, mean = turn_statistic(a, b, *covs)  # compiled (window_kernels)
    if not ok:
        raise np.linalg.LinAlgError("Singular matrix")
    if chdtrc(3 * (n - 1), statistic) < 0.5 * TURN_ALPHA:  # P(χ² > statistic), chi2.sf's own function
        return PairTurn(cap, mean)
    if chdtrc(3, turn_score(a, b, *covs, mean, REFERENCE_FRAMES)) < 0.5 * TURN_ALPHA:  # compiled (window_kernels)
        return PairTurn(cap, mean)
    return PairTurn(-QUIET_WEIGHT if np.linalg.norm(mean) >= QUIET_PAIR_M else 0.0, mean)


def turn_log_odds(points_a, points_b, covs_a, covs_b, cap: float = TURN_CAP) -> float:
    """The log-odds of :func:`turn_evidence` alone."""
    return turn_evidence(points_a, points_b, covs_a, covs_b, cap).log_odds


def quiet_log_odds(quiet: list[PairTurn], spread_deg: float = QUIET_SPREAD_DEG) -> float:
    """A body's slide evidence from its quiet pairs (SPEC 13, 18): their votes add, provided two of
    them differ in direction by more than ``spread_deg`` (sign aside), else 0.

    A turn leaves a pair's difference unchanged only if the pair lies along the hinge; two pairs
    along different directions cannot both, so together they rule a turn out. Pairs all along one
    line (a door's points up its edge, parallel to its hinge) are quiet under a turn as well: the
    kitchen's wall cabinet door, three points whose pairs lie within 20° of its hinge, ended as a
    slider for all 60 of its points over 20 seeds while those votes counted, for 30 after. The 30°
    separates such a door from a drawer front, whose handle-to-corner pairs spread 45–90°; it was
    chosen from the two geometries, not tuned on outcomes.
    """
    if not quiet:
        return 0.0
    offsets = np.array([turn.offset for turn in quiet]).reshape(-1, 3)
    units = offsets / np.maximum(np.linalg.norm(offsets, axis=1), 1e-12)[:, None]
    if np.abs(units @ units.T).min() >= math.cos(math.radians(spread_deg)):
        return 0.0
    return float(sum(turn.log_odds for turn in quiet))
