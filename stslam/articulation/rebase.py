"""Re-express a landmark's motion state on a refitted structure (SPEC 2, 3, 6.3(b)).

A-SLAM refines the structure C of an articulated landmark on its growing
window of observations; the motion state X = [q, q⁽¹⁾, …, q⁽ᵏ⁾] in the SLAM
state then has to move from the old structure C to the new one C′ without
losing what the filter knows. The map g used here, for models with a scalar
motion variable (prismatic l in m, revolute φ in rad; SPEC 2.2, 2.3):

    m     = f(C, q)                       the landmark's point on the old path (m, world)
    q′    = IK(C′, m)                     inverse kinematics on the new path
    s(q)  = ∇IK(C′, m)ᵀ ∂f/∂q(C, q)      dq′/dq, the speed ratio of the two parametrisations
    q′⁽ᵈ⁾ = s(q) · q⁽ᵈ⁾,  d = 1 … k        derivatives carried by the chain rule

The derivative rows keep only the first-order term of the chain rule (the
curvature terms s′(q)·(q⁽¹⁾)² of an acceleration are dropped): exact for
velocities, and exact for every order when s is constant (a line refitted to
a line). Its Jacobian J = ∂X′/∂X (k+1, k+1) has s(q) on the diagonal and
s′(q)·q⁽ᵈ⁾ in the first column, with

    s′(q) = ∂f/∂qᵀ · ∇²IK(C′, m) · ∂f/∂q + ∇IK(C′, m)ᵀ · ∂²f/∂q².

The covariance then follows by first-order propagation, J P Jᵀ
(:meth:`stslam.slam.core.SlamState.replace_block`).
"""

from __future__ import annotations

import numpy as np

from stslam.articulation.models import MODELS, PrismaticStructure, RevoluteStructure

_PATH_MODELS = {PrismaticStructure: MODELS["prismatic"], RevoluteStructure: MODELS["revolute"]}


def path_derivatives(structure, q: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """f(C, q), ∂f/∂q and ∂²f/∂q² of a prismatic or revolute path, each shape (3,) (m, m/unit, m/unit²).

    The articulation model's own kinematics (:mod:`stslam.articulation.models`):
    prismatic (SPEC 2.2) f = P0 + l n̂, f′ = n̂, f″ = 0; revolute (SPEC 2.3)
    f = (x0 + r cos φ) v1 + (y0 + r sin φ) v2 + P0, f′ = r(−sin φ v1 + cos φ v2),
    f″ = −r(cos φ v1 + sin φ v2).
    """
    model = _PATH_MODELS.get(type(structure))
    if model is None:
        raise ValueError(f"path_derivatives: expected a prismatic or revolute structure, "
                         f"got {type(structure).__name__}")
    q1 = np.array([q], dtype=float)
    return (model.position(structure, q1), model.jacobian(structure, q1)[:, 0],
            model.second_derivative(structure, q1)[:, 0, 0])


def inverse_kinematics_derivatives(structure, m_world) -> tuple[float, np.ndarray, np.ndarray]:
    """q = IK(C, m), its gradient ∇q (3,) and Hessian ∇²q (3, 3) at a world point m (m).

    Prismatic (SPEC 2.2): q = n̂ᵀ(m − P0), ∇q = n̂, ∇²q = 0.
    Revolute (SPEC 2.3): with in-plane offsets a = v1ᵀ(m − P0) − x0 and
    b = v2ᵀ(m − P0) − y0, ρ² = a² + b², q = atan2(b, a) in (−π, π],
    ∇q = (a v2 − b v1)/ρ²,
    ∇²q = (v2 v1ᵀ − v1 v2ᵀ)/ρ² − 2 (a v2 − b v1)(a v1 + b v2)ᵀ/ρ⁴ (symmetric).
    """
    m = np.asarray(m_world, dtype=float).reshape(3)
    if isinstance(structure, PrismaticStructure):
        n = structure.direction
        return float(n @ (m - structure.p0)), n.copy(), np.zeros((3, 3))
    if isinstance(structure, RevoluteStructure):
        v1, v2 = structure.v1, structure.v2
        a = float(v1 @ (m - structure.p0) - structure.centre_xy[0])
        b = float(v2 @ (m - structure.p0) - structure.centre_xy[1])
        rho2 = a * a + b * b
        if rho2 == 0.0:
            raise ValueError("inverse kinematics is undefined on the joint axis (zero in-plane offset)")
        tangent = a * v2 - b * v1
        hessian = (np.outer(v2, v1) - np.outer(v1, v2)) / rho2 - 2.0 * np.outer(tangent, a * v1 + b * v2) / rho2**2
        return float(np.arctan2(b, a)), tangent / rho2, hessian
    raise ValueError(f"inverse_kinematics_derivatives: expected a prismatic or revolute structure, "
                     f"got {type(structure).__name__}")


def rebase_motion_state(structure_old, structure_new, X) -> tuple[np.ndarray, np.ndarray]:
    """The motion state X (k+1,) on ``structure_old`` re-expressed on ``structure_new`` (module docstring).

    Parameters
    ----------
    structure_old, structure_new : PrismaticStructure or RevoluteStructure
        Old and refitted structure (any combination of the two kinds).
    X : array_like, shape (k+1,)
        [q, q⁽¹⁾, …, q⁽ᵏ⁾] on the old structure (m or rad, per time^d).

    Returns
    -------
    X_new : numpy.ndarray, shape (k+1,)
    J : numpy.ndarray, shape (k+1, k+1)
        ∂X_new/∂X.
    """
    X = np.asarray(X, dtype=float).reshape(-1)
    m, f1, f2 = path_derivatives(structure_old, float(X[0]))
    q_new, grad, hessian = inverse_kinematics_derivatives(structure_new, m)
    speed_ratio = float(grad @ f1)  # s(q) = ∇IKᵀ f′
    d_speed_ratio = float(f1 @ hessian @ f1 + grad @ f2)  # s′(q)
    X_new = np.empty_like(X)
    X_new[0] = q_new
    X_new[1:] = speed_ratio * X[1:]
    J = speed_ratio * np.eye(X.size)
    J[1:, 0] = d_speed_ratio * X[1:]
    return X_new, J
