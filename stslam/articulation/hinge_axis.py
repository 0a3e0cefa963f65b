"""One hinge axis from many revolute point tracks: clustering and a robust joint fit (SPEC 2.3, 8.5).

Every point on a door turns about the same hinge: the tracks the selector
classified as revolute (SPEC 4) each give an axis (SPEC 2.3: the line through
the circle centre along the plane normal). The door is the largest group of
tracks whose axes agree (:func:`cluster_axes`); its axis is then fitted from
all points of all tracks of the group at once (:func:`fit_common_axis`).

Joint model, for an axis through p with unit direction a: point x of track i
lies on a circle about the axis, at a height along the axis and a radius of
its own, so the residuals are

    e_r = ‖(x − p) − ((x − p)·a) a‖ − r_i        (radial, m)
    e_h = (x − p)·a − h_i                          (axial, m)

with r_i, h_i the track's means (the least-squares values for a fixed axis:
variable projection). The axis has 4 degrees of freedom: a is written as the
initial direction a₀ turned by small angles (α, β) about two unit vectors
e₁, e₂ ⟂ a₀, and p = p₀ + s e₁ + t e₂. The fit is an M-estimator
(``scipy.optimize.least_squares`` with the soft-L1 loss); tracks whose RMS
residual stays above ``trim_factor`` × the median track's are then dropped and
the axis refitted once (a track that slid along an edge, or a static point
clustered by chance).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from stslam.articulation.models import RevoluteStructure
from stslam.checks import check_fields, check_int
from stslam.errors import DegenerateFitError
from stslam.geometry import cross3, pairwise_axis_angles_deg, pairwise_axis_line_distances


@dataclass(frozen=True)
class AxisTolerance:
    """How far two fitted joints may differ and still be one joint (SPEC 7's axis errors).

    Directions within ``max_angle_deg`` (either sign) and, for revolute joints, axis
    lines within ``max_distance_m`` (m).
    """

    max_angle_deg: float = 15.0
    max_distance_m: float = 0.15

    def __post_init__(self):
        check_fields(self, max_angle_deg="(0, 90]", max_distance_m="(0, inf)")


@dataclass(frozen=True)
class HingeAxisOptions:
    """How :func:`estimate_hinge_axis` groups and fits revolute tracks.

    Tracks whose axes agree within ``tolerance`` (one joint, as bodies'
    joints agree: directions within ``max_angle_deg``, axis lines within
    ``max_distance_m``; config keys beside the others) form a cluster; the
    largest needs ``min_tracks`` members; the joint fit is soft-L1 with scale
    ``scale_m`` (m), trimmed at ``trim_factor`` times its robust residual spread.
    """

    tolerance: AxisTolerance = AxisTolerance(max_angle_deg=10.0, max_distance_m=0.1)
    min_tracks: int = 2
    scale_m: float = 0.02
    trim_factor: float = 3.0

    def __post_init__(self):
        check_fields(self, scale_m="(0, inf)", trim_factor="[1, inf)")
        check_int("min_tracks", self.min_tracks, low=2)


@dataclass(frozen=True)
class HingeAxis:
    """A fitted hinge axis.

    Attributes
    ----------
    point_world : numpy.ndarray, shape (3,)
        A point on the axis (m, world frame): the one nearest the members' centroid.
    direction_world : numpy.ndarray, shape (3,)
        Unit direction, sign chosen with a non-negative z (sign-blind quantity).
    member_ids : tuple
        Track ids of the cluster the fit started from.
    inlier_ids : tuple
        Track ids kept after trimming.
    track_rms_m : dict
        Track id → RMS of its residuals (e_r, e_h) at the final axis (m).
    height_range_m : tuple[float, float]
        Extent of the inliers' points along the axis from ``point_world`` (m), for drawing.
    """

    point_world: np.ndarray
    direction_world: np.ndarray
    member_ids: tuple
    inlier_ids: tuple
    track_rms_m: dict
    height_range_m: tuple


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v)


def canonical_direction(direction) -> np.ndarray:
    """Unit ``direction`` (3,) with its sign chosen so that z ≥ 0 (then y, then x, for horizontal axes)."""
    d = _unit(direction)
    for c in (2, 1, 0):
        if abs(d[c]) > 1e-12:
            return d if d[c] > 0 else -d
    return d


def cluster_axes(axis_points, axis_directions, max_angle_deg: float, max_distance_m: float) -> list[np.ndarray]:
    """Greedy clusters of axes (n lines) that agree within an angle and a line-to-line distance.

    Each round takes the axis with the most others within ``max_angle_deg``
    (SPEC 7 sign-blind angle) and ``max_distance_m`` (line distance) of it,
    makes that set a cluster and removes it (ties: the lowest index).
    Returns index arrays, largest cluster first.
    """
    points = np.asarray(axis_points, dtype=float).reshape(-1, 3)
    dirs = np.asarray(axis_directions, dtype=float).reshape(-1, 3)
    n = points.shape[0]
    agree = ((pairwise_axis_angles_deg(dirs, dirs) <= max_angle_deg)
             & (pairwise_axis_line_distances(points, dirs, points, dirs) <= max_distance_m))
    left = np.ones(n, dtype=bool)
    clusters = []
    while left.any():
        counts = np.where(left, (agree & left[None, :]).sum(axis=1), -1)
        seed = int(np.argmax(counts))
        members = np.flatnonzero(agree[seed] & left)
        clusters.append(members)
        left[members] = False
    return clusters


def axis_basis(a0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors (3,) completing a0 to a right-handed orthonormal basis."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(a0[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = _unit(cross3(a0, helper))
    return e1, cross3(a0, e1)


def axis_from_parameters(theta, p0, a0, e1, e2) -> tuple[np.ndarray, np.ndarray]:
    """Axis (point (3,), unit direction (3,)) of the 4 parameters θ = (α, β, s, t) about (p0, a0) (module docstring)."""
    alpha, beta, s, t = theta
    a = _unit(a0 + np.tan(alpha) * e1 + np.tan(beta) * e2)
    return p0 + s * e1 + t * e2, a


def axis_residuals(point_world, direction_world, point_sets) -> list[np.ndarray]:
    """Per track, residuals (m_i, 2) = (e_r, e_h) of its points about the axis (module docstring)."""
    sets = [np.asarray(P, dtype=float).reshape(-1, 3) for P in point_sets]
    sizes = [P.shape[0] for P in sets]
    flat = _stacked_residuals(point_world, direction_world, np.concatenate(sets), sizes).reshape(-1, 2)
    return np.split(flat, np.cumsum(sizes)[:-1])


def _stacked_residuals(point_world, direction_world, points, sizes) -> np.ndarray:
    """:func:`axis_residuals` of the tracks stacked in ``points`` (Σm_i, 3), ``sizes`` m_i each, as one flat
    vector (e_r, e_h, e_r, …): one pass over all points, each track's means taken on its own slice (the same
    numbers as track by track)."""
    p, a = np.asarray(point_world, dtype=float), _unit(direction_world)
    d = points - p
    h = d @ a
    r = np.linalg.norm(d - np.outer(h, a), axis=1)
    ends = np.cumsum(sizes).tolist()
    starts = [0, *ends[:-1]]
    r_means = np.repeat([r[i:j].mean() for i, j in zip(starts, ends)], sizes)
    h_means = np.repeat([h[i:j].mean() for i, j in zip(starts, ends)], sizes)
    return np.column_stack([r - r_means, h - h_means]).reshape(-1)


def _solve(point_sets, p0, a0, scale_m: float) -> tuple[np.ndarray, np.ndarray]:
    e1, e2 = axis_basis(a0)
    points, sizes = np.concatenate(point_sets), [len(P) for P in point_sets]

    def fun(theta):
        p, a = axis_from_parameters(theta, p0, a0, e1, e2)
        return _stacked_residuals(p, a, points, sizes)

    result = least_squares(fun, np.zeros(4), loss="soft_l1", f_scale=scale_m, x_scale=[0.1, 0.1, 0.1, 0.1])
    return axis_from_parameters(result.x, p0, a0, e1, e2)


def fit_common_axis(point_sets, initial_point, initial_direction, *, scale_m: float = 0.02,
                    trim_factor: float = 3.0, min_rms_m: float = 0.01, ids=None) -> HingeAxis:
    """Axis shared by the circles of several tracks (module docstring), robust to a few bad tracks.

    Parameters
    ----------
    point_sets : list of numpy.ndarray, each (m_i, 3)
        World points (m) of each track.
    initial_point, initial_direction : array_like, shape (3,)
        Starting axis (e.g. the cluster's median axis).
    scale_m : float
        Soft-L1 scale: residuals well above it count linearly (m).
    trim_factor, min_rms_m : float
        After the first fit, tracks with RMS > max(trim_factor × median RMS, min_rms_m) are dropped.
    ids : sequence, optional
        Track ids (default 0 … n − 1).

    Raises
    ------
    DegenerateFitError
        Fewer than 2 tracks, or a track with fewer than 3 points.
    """
    sets = [np.asarray(P, dtype=float).reshape(-1, 3) for P in point_sets]
    ids = tuple(range(len(sets))) if ids is None else tuple(ids)
    if len(sets) < 2 or min(P.shape[0] for P in sets) < 3:
        raise DegenerateFitError(f"a common axis needs ≥ 2 tracks of ≥ 3 points; got {len(sets)} track(s) "
                                 f"of {[P.shape[0] for P in sets]} points")
    a0 = canonical_direction(initial_direction)
    p, a = _solve(sets, np.asarray(initial_point, dtype=float), a0, scale_m)
    rms = np.array([np.sqrt(np.mean(e**2)) for e in axis_residuals(p, a, sets)])
    keep = rms <= max(trim_factor * np.median(rms), min_rms_m)
    if 2 <= keep.sum() < len(sets):
        p, a = _solve([P for P, k in zip(sets, keep) if k], p, a, scale_m)
        rms = np.array([np.sqrt(np.mean(e**2)) for e in axis_residuals(p, a, sets)])
    a = canonical_direction(a)
    inliers = [P for P, k in zip(sets, keep) if k]
    centroid = np.vstack(inliers).mean(axis=0)
    p = p + ((centroid - p) @ a) * a
    heights = np.vstack(inliers) @ a - p @ a
    return HingeAxis(point_world=p, direction_world=a, member_ids=ids,
                     inlier_ids=tuple(i for i, k in zip(ids, keep) if k),
                     track_rms_m={i: float(v) for i, v in zip(ids, rms)},
                     height_range_m=(float(heights.min()), float(heights.max())))


def estimate_hinge_axis(axes: dict, point_sets: dict, options: HingeAxisOptions = HingeAxisOptions()) -> HingeAxis:
    """The hinge from revolute tracks: largest agreeing cluster, then the joint robust fit.

    Parameters
    ----------
    axes : dict
        Track id → (axis point (3,), axis direction (3,)) of each revolute track (m, world).
    point_sets : dict
        Track id → its world points (m_i, 3) (m).
    options : HingeAxisOptions

    Raises
    ------
    DegenerateFitError
        Fewer than ``options.min_tracks`` revolute tracks agree on an axis.
    """
    min_tracks = options.min_tracks
    ids = sorted(axes)
    if len(ids) < min_tracks:
        raise DegenerateFitError(f"{len(ids)} revolute track(s); a hinge axis needs at least {min_tracks}")
    points = np.array([axes[i][0] for i in ids])
    dirs = np.array([canonical_direction(axes[i][1]) for i in ids])
    best = cluster_axes(points, dirs, options.tolerance.max_angle_deg, options.tolerance.max_distance_m)[0]
    if best.size < min_tracks:
        raise DegenerateFitError(f"the largest group of agreeing revolute tracks has {best.size} track(s); "
                                 f"a hinge axis needs at least {min_tracks}")
    members = [ids[j] for j in best]
    # Start from the member axis nearest to all others (a medoid), robust to one stray axis.
    angles = pairwise_axis_angles_deg(dirs[best], dirs[best])
    cost = [sum(row.tolist()) for row in angles]  # summed in order, as one pair at a time
    start = best[int(np.argmin(cost))]
    return fit_common_axis([point_sets[i] for i in members], points[start], dirs[start], scale_m=options.scale_m,
                           trim_factor=options.trim_factor, ids=members)


def circle_on_axis(axis_point_world, axis_direction_world, points_world) -> RevoluteStructure:
    """The revolute structure (SPEC 2.3) of one track's points (m, 3) about a given axis.

    The circle lies in the plane ⟂ a at the points' mean height h along the axis,
    centred on the axis, with radius r = the points' mean distance from it (the
    least-squares r_i, h_i of the joint model above). p0 = the centre, v1 ⟂ a
    and v2 = a × v1, so v1 × v2 = a: φ grows by the right-hand rule about a.
    """
    a = _unit(axis_direction_world)
    p = np.asarray(axis_point_world, dtype=float)
    P = np.asarray(points_world, dtype=float).reshape(-1, 3)
    d = P - p
    h = d @ a
    radial = d - np.outer(h, a)
    r = np.linalg.norm(radial, axis=1)
    if P.shape[0] < 1 or r.mean() <= 0:
        raise DegenerateFitError("a circle about the axis needs points off the axis")
    v1, v2 = axis_basis(a)
    v2 = cross3(a, v1)
    residual = float(np.sqrt(np.mean((r - r.mean()) ** 2 + (h - h.mean()) ** 2)))
    return RevoluteStructure(p0=p + h.mean() * a, v1=v1, v2=v2, centre_xy=np.zeros(2), radius=float(r.mean()),
                             residual_m=residual)
