"""Articulated bodies: many points on one joint with one motion variable (SPEC 13).

A body is a joint (revolute: a point a on the axis and its unit direction â;
prismatic: a unit slide direction n̂) and, per member point i, a fixed offset:
its position p_i,ref at the body's reference q_ref. Then

* revolute:  p_i(φ) = a + R(â, φ − φ_ref)(p_i,ref − a)   (R by Rodrigues, right-handed about â)
* prismatic: p_i(l) = p_i,ref + (l − l_ref)·n̂

with ∂p_i/∂φ = â × (p_i(φ) − a) and ∂p_i/∂l = n̂ (chain rule through the
rotation: dR(â, θ)/dθ = [â]× R(â, θ)).

Each member is then a landmark of the ordinary model on its own structure
(:func:`member_structure`): the circle about the axis through p_i,ref, or the
line through it along n̂, both in the *body's* q, so a member's observation
is the SPEC 2 kinematics of one point and updates the body's motion state.

Grouping (:func:`rigidity_test`): two tracks on one rigid body keep their
distance; a pose error moves both points of a frame by one rigid transform,
which keeps it too, so only the sensor noise enters the test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import chdtrc

from stslam.articulation.hinge_axis import AxisTolerance
from stslam.articulation.models import PrismaticStructure, RevoluteStructure
from stslam.geometry import axis_angle_deg, axis_line_distance, cross3, rotation_about_axis
from stslam.slam.bodies.pair_kernels import rigidity_kernel

__all__ = ["BodyJoint", "RigidityTest", "axes_agree", "joint_of", "member_jacobian", "member_offset",
           "member_offset_covariance", "member_fit_test", "member_position", "member_structure", "off_axis",
           "rigidity_test"]

SPREAD_BLOCK = 5  # observations per block mean of RigidityTest.spread_m
MIN_RADIUS_M = 0.01  # a member this close to the hinge axis barely moves: no circle to put it on


@dataclass(frozen=True, eq=False)
class BodyJoint:
    """The joint of a body (SPEC 13).

    Attributes
    ----------
    model_name : {"prismatic", "revolute"}
    point : numpy.ndarray, shape (3,)
        A point a on the hinge axis (m, world frame); unused for prismatic.
    direction : numpy.ndarray, shape (3,)
        Unit axis â (revolute, φ right-handed about it) or slide direction n̂ (prismatic).
    """

    model_name: str
    point: np.ndarray
    direction: np.ndarray


def joint_of(model_name: str, structure) -> BodyJoint:
    """The joint of a landmark's fitted structure (SPEC 2): the circle's axis, or the line's direction."""
    if model_name == "revolute":
        return BodyJoint("revolute", np.asarray(structure.axis_point, float), np.asarray(structure.normal, float))
    if model_name == "prismatic":
        return BodyJoint("prismatic", np.asarray(structure.p0, float), np.asarray(structure.direction, float))
    raise ValueError(f"model_name: expected prismatic or revolute, got {model_name!r}")


def member_position(joint: BodyJoint, p_ref, q_ref: float, q: float) -> np.ndarray:
    """p_i(q) (3,) of the member at ``p_ref`` (3,) when the body was at ``q_ref`` (SPEC 13)."""
    p_ref = np.asarray(p_ref, dtype=float)
    if joint.model_name == "prismatic":
        return p_ref + (q - q_ref) * joint.direction
    return joint.point + rotation_about_axis(joint.direction, q - q_ref) @ (p_ref - joint.point)


def member_jacobian(joint: BodyJoint, p_ref, q_ref: float, q: float) -> np.ndarray:
    """∂p_i/∂q (3, 1): n̂ (prismatic), â × (p_i(φ) − a) (revolute, dR/dθ = [â]× R)."""
    if joint.model_name == "prismatic":
        return joint.direction.reshape(3, 1).copy()
    p = member_position(joint, p_ref, q_ref, q)
    return cross3(joint.direction, p - joint.point).reshape(3, 1)


def member_offset(joint: BodyJoint, points, qs) -> np.ndarray:
    """The member's position at q = 0 (3,), the mean of its observed points (n, 3) taken back from the
    body's q at each (qs (n,)): least squares of the fixed offset given the body's motion."""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    qs = np.asarray(qs, dtype=float).reshape(-1)
    if points.shape[0] == 0 or points.shape[0] != qs.size:
        raise ValueError(f"points, qs: expected n ≥ 1 points and n angles, got {points.shape} and {qs.shape}")
    back = [member_position(joint, p, q, 0.0) for p, q in zip(points, qs, strict=True)]
    return np.mean(back, axis=0)


def member_offset_covariance(joint: BodyJoint, qs, sensor_covs, pose_covs) -> np.ndarray:
    """Covariance (3, 3) of :func:`member_offset`'s p_zero, the mean of n points taken back to q = 0.

    Each point t is turned back by B_t = R(â, −q_t) (revolute; I for a slide), so p_zero's error is the mean
    of B_t e_t. The sensor's share of e_t (``sensor_covs`` (n, 3, 3), independent between frames) enters as
    Σ_t B_t R_t B_tᵀ / n²; the pose's share (``pose_covs`` (n, 3, 3), J_pose P_pose J_poseᵀ, SPEC 5.2) is the
    slowly varying error of one robot estimate over the window, so it is not averaged down: its mean
    Σ_t B_t S_t B_tᵀ / n enters whole.
    """
    qs = np.asarray(qs, dtype=float).reshape(-1)
    sensor = np.asarray(sensor_covs, dtype=float).reshape(-1, 3, 3)
    pose = np.asarray(pose_covs, dtype=float).reshape(-1, 3, 3)
    if not (qs.size == sensor.shape[0] == pose.shape[0] and qs.size >= 1):
        raise ValueError(f"qs, sensor_covs, pose_covs: expected n ≥ 1 of each, got {qs.size}, {sensor.shape[0]}, "
                         f"{pose.shape[0]}")
    n = qs.size
    if joint.model_name == "prismatic":
        back = np.broadcast_to(np.eye(3), (n, 3, 3))
    else:
        back = np.array([rotation_about_axis(joint.direction, -q) for q in qs])
    turned = lambda covs: np.einsum("nij,njk,nlk->il", back, covs, back)  # Σ_t B_t C_t B_tᵀ
    cov = turned(sensor) / n**2 + turned(pose) / n
    return 0.5 * (cov + cov.T)


def member_fit_test(joint: BodyJoint, points, qs, covs) -> tuple[np.ndarray, float]:
    """Does a track move as a member of the body? (p_zero (3,), χ² p-value)

    p_zero by :func:`member_offset`; residuals r_t = p_t − p_i(q_t) with
    covariances Σ_t (n, 3, 3): Σ_t r_tᵀ Σ_t⁻¹ r_t is χ²(3n − 3) for a member
    (three offset coordinates fitted). Stronger than the distance test: it
    uses all three coordinates and the body's estimated q.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    qs = np.asarray(qs, dtype=float).reshape(-1)
    p_zero = member_offset(joint, points, qs)
    r = points - np.array([member_position(joint, p_zero, 0.0, q) for q in qs])
    stat = float(np.einsum("ni,ni->", r, np.linalg.solve(np.asarray(covs, dtype=float), r[..., None])[..., 0]))
    dof = 3 * points.shape[0] - 3
    return p_zero, _chi2_sf(stat, dof) if dof > 0 else 1.0


def member_structure(joint: BodyJoint, p_zero):
    """The SPEC 2 structure on which the member at ``p_zero`` (its position at q = 0) moves in the body's q.

    Prismatic: the line p_zero + l·n̂. Revolute: the circle about the axis
    through p_zero, centre its foot on the axis, v1 towards p_zero (φ = 0
    there), v2 = â × v1, so f(C, φ) = p_i(φ) of :func:`member_position` with
    q_ref = 0. Raises ValueError for a point within ``MIN_RADIUS_M`` of the axis.
    """
    p_zero = np.asarray(p_zero, dtype=float)
    if joint.model_name == "prismatic":
        return PrismaticStructure(p0=p_zero, direction=joint.direction, residual_m=0.0)
    foot = joint.point + ((p_zero - joint.point) @ joint.direction) * joint.direction
    radius = float(np.linalg.norm(p_zero - foot))
    if radius < MIN_RADIUS_M:
        raise ValueError(f"p_zero: expected a point at least {MIN_RADIUS_M} m off the axis, got {radius:.4f} m")
    v1 = (p_zero - foot) / radius
    return RevoluteStructure(p0=foot, v1=v1, v2=cross3(joint.direction, v1), centre_xy=np.zeros(2),
                             radius=radius, residual_m=0.0)


def off_axis(joint: BodyJoint, p) -> np.ndarray:
    """``p`` (3,) moved radially (along the foot → p direction, or any normal to the axis if it is on it) to
    ``MIN_RADIUS_M`` from a revolute joint's axis when it is closer: a point :func:`member_structure` accepts."""
    p = np.asarray(p, dtype=float)
    foot = joint.point + ((p - joint.point) @ joint.direction) * joint.direction
    out = p - foot
    if np.linalg.norm(out) < 1e-9:  # on the axis: any direction normal to it
        out = cross3(joint.direction, np.eye(3)[int(np.argmin(np.abs(joint.direction)))])
    out = out / np.linalg.norm(out)
    return p if np.linalg.norm(p - foot) >= MIN_RADIUS_M else foot + (1.0 + 1e-9) * MIN_RADIUS_M * out


def axes_agree(a: BodyJoint, b: BodyJoint, tolerance: AxisTolerance) -> bool:
    """Whether two joints are one: the same model and axes within ``tolerance``."""
    if a.model_name != b.model_name:
        return False
    if axis_angle_deg(a.direction, b.direction) > tolerance.max_angle_deg:
        return False
    return a.model_name == "prismatic" or \
        axis_line_distance(a.point, a.direction, b.point, b.direction) <= tolerance.max_distance_m


@dataclass(frozen=True)
class RigidityTest:
    """Result of :func:`rigidity_test`.

    Attributes
    ----------
    statistic : float
        Σ_t (d_t − d̄)² / var_t, χ²(n − 1) for a rigid pair.
    dof : int
        n − 1.
    p_value : float
        χ² survival probability of the statistic.
    spread_m : float
        How far the track that moved less moved over the frames (m): the
        largest distance between the means of two blocks of ``SPREAD_BLOCK``
        consecutive observations (a mean, not a point: one point's noise alone
        spreads a window by several σ). The test only tells rigid from not
        when both moved: two resting points keep their distance too.
    """

    statistic: float
    dof: int
    p_value: float
    spread_m: float

    @classmethod
    def of(cls, statistic: float, dof: int, spread_m: float) -> "RigidityTest":
        """The test of a statistic and its dof (:func:`stslam.slam.bodies.pair_kernels.rigidity_kernel`)."""
        statistic, dof = float(statistic), int(dof)
        return cls(statistic, dof, _chi2_sf(statistic, dof) if dof else 1.0, float(spread_m))

    def consistent(self, significance: float, min_spread_m: float) -> bool:
        """Rigid at level ``significance`` and moved more than ``min_spread_m`` over the frames."""
        return self.dof >= 1 and self.p_value > significance and self.spread_m > min_spread_m


def rigidity_test(points_a, points_b, covs_a, covs_b) -> RigidityTest:
    """Are two tracks, observed at the same n frames, at constant distance? (SPEC 13 grouping)

    d_t = |p_a,t − p_b,t| with variance var_t = u_tᵀ(Σ_a,t + Σ_b,t)u_t, u_t the
    unit vector between them (first order); d̄ the inverse-variance weighted
    mean; Σ_t (d_t − d̄)²/var_t is χ²(n − 1) under rigidity.

    Parameters
    ----------
    points_a, points_b : array_like, shape (n, 3)
        World points of the two tracks at the same frames (m).
    covs_a, covs_b : array_like, shape (n, 3, 3)
        Their sensor-noise covariances in the world frame (m²).
    """
    a = np.asarray(points_a, dtype=float).reshape(-1, 3)
    b = np.asarray(points_b, dtype=float).reshape(-1, 3)
    if a.shape != b.shape:
        raise ValueError(f"points_a, points_b: expected the same shape, got {a.shape} and {b.shape}")
    ca = np.asarray(covs_a, dtype=float).reshape(-1, 3, 3)
    cb = np.asarray(covs_b, dtype=float).reshape(-1, 3, 3)
    return RigidityTest.of(*rigidity_kernel(a, b, ca, cb, SPREAD_BLOCK))  # the formulas above, compiled


def _chi2_sf(statistic: float, dof: int) -> float:
    """P(χ²_dof > statistic), as ``scipy.stats.chi2.sf`` gives it (1 at or below 0), by its own function
    ``chdtrc`` without the distribution's argument handling."""
    return 1.0 if statistic <= 0.0 else float(chdtrc(dof, statistic))
