"""Articulation models: structure C, motion variable q and f(C, q) (SPEC 2, paper §III-A).

A model M explains a moving point by z = f_M(C, q) + ν with time-invariant
structure C and time-varying motion variable q (shape (dof,)). All points are
3D, world frame, metres; angles in radians.

=========  ===========================  ============  ===========================
model      structure C                  q             f(C, q)
=========  ===========================  ============  ===========================
static     P0                           l  (m)        P0 + l·[1,1,1]ᵀ   (SPEC 2.1)
 isotropic P0                           δ (3,) (m)    P0 + δ
prismatic  P0, n̂                        l  (m)        P0 + l·n̂          (SPEC 2.2)
revolute   P0, v1, v2, (x0, y0), r      φ  (rad)      (x0 + r cos φ)·v1
                                                      + (y0 + r sin φ)·v2 + P0
                                                                        (SPEC 2.3)
=========  ===========================  ============  ===========================

Conventions, written once:

* prismatic n̂ points so that l grows over the fit window (SPEC 2.2);
* revolute v1, v2 are orthonormal with v2 chosen so that φ grows over the fit
  window; the normal v1 × v2 is then the joint axis by the right-hand rule
  (the point turns counter-clockwise seen from the tip of the normal);
* ``residual_m`` of every structure is the RMS distance (m) of the fit window's
  points to the fitted point, line or circle.

Fits are pure functions of the window; degenerate windows raise
:class:`~stslam.errors.DegenerateFitError` with the reason (SPEC 2.4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stslam.articulation.circle_fit import raise_degenerate
from stslam.articulation.circle_kernels import line_fit, revolute_angles, revolute_fit
from stslam.errors import DegenerateFitError
from stslam.geometry import cross3

ONES3 = np.ones(3)


# --------------------------------------------------------------------------- checks

def check_points_world(points_world) -> np.ndarray:
    """Float64 copy of 3D points, shape (n, 3), n ≥ 1; ValueError for a wrong shape or NaN."""
    p = np.asarray(points_world, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] < 1:
        raise ValueError(f"points_world must have shape (n, 3) with n ≥ 1, got {p.shape}")
    if not np.isfinite(p).all():  # (the method: numpy's np.all wrapper costs more than the test on a window)
        raise ValueError("points_world contains non-finite values")
    return p


def _check_q(q, dof: int) -> tuple[np.ndarray, bool]:
    """q as shape (n, dof) and whether the input was a single q of shape (dof,)."""
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 and dof == 1:
        return q.reshape(1, 1), True
    if q.ndim == 1 and q.shape[0] == dof:
        return q.reshape(1, dof), True
    if q.ndim == 2 and q.shape[1] == dof:
        return q, False
    raise ValueError(f"q must have shape ({dof},) or (n, {dof}), got {q.shape}")


# ----------------------------------------------------------------------- structures

@dataclass(frozen=True, eq=False)
class StaticStructure:
    """Static point (SPEC 2.1): ``p0`` (3,) m; ``residual_m`` RMS distance to p0."""

    p0: np.ndarray
    residual_m: float


@dataclass(frozen=True, eq=False)
class PrismaticStructure:
    """Line (SPEC 2.2): point ``p0`` (3,) m, unit ``direction`` (3,); ``residual_m`` RMS distance to the line."""

    p0: np.ndarray
    direction: np.ndarray
    residual_m: float


@dataclass(frozen=True, eq=False)
class RevoluteStructure:
    """Circle in a plane (SPEC 2.3).

    Attributes
    ----------
    p0 : numpy.ndarray, shape (3,)
        Origin of the plane coordinates (m, world frame).
    v1, v2 : numpy.ndarray, shape (3,)
        Orthonormal in-plane axes (world frame); φ grows over the fit window.
    centre_xy : numpy.ndarray, shape (2,)
        Circle centre (x0, y0) in plane coordinates (m).
    radius : float
        Circle radius r (m).
    residual_m : float
        RMS 3D distance of the fit window's points to the circle (m).
    """

    p0: np.ndarray
    v1: np.ndarray
    v2: np.ndarray
    centre_xy: np.ndarray
    radius: float
    residual_m: float

    @property
    def normal(self) -> np.ndarray:
        """Unit plane normal v1 × v2 (3,): the rotation axis, right-handed in φ."""
        return cross3(self.v1, self.v2)

    @property
    def centre_world(self) -> np.ndarray:
        """Circle centre P0 + x0·v1 + y0·v2 (3,), m, world frame."""
        return self.p0 + self.centre_xy[0] * self.v1 + self.centre_xy[1] * self.v2

    @property
    def axis_direction(self) -> np.ndarray:
        """Direction of the joint axis (3,): the unit normal (SPEC 2.3)."""
        return self.normal

    @property
    def axis_point(self) -> np.ndarray:
        """A point on the joint axis (3,), m: the circle centre (SPEC 2.3)."""
        return self.centre_world


# --------------------------------------------------------------------------- models

class _JointModel:
    """What the three models share: ``name``, ``dof`` and a plain ``repr``."""

    name: str
    dof: int

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class StaticModel(_JointModel):
    """Static point, f(C, l) = P0 + l·[1,1,1]ᵀ (SPEC 2.1).

    Parameters
    ----------
    perturbation : {"paper", "isotropic"}
        ``"paper"`` (default): the paper's scalar perturbation along [1,1,1]
        (dof 1). ``"isotropic"``: a 3D offset δ with f = P0 + δ (dof 3), so a
        random walk on q perturbs the point equally in every direction.
    """

    name = "static"

    def __init__(self, perturbation: str = "paper"):
        if perturbation not in ("paper", "isotropic"):
            raise ValueError(f"perturbation: expected one of paper, isotropic; got {perturbation!r}")
        self.perturbation = perturbation
        self.dof = 1 if perturbation == "paper" else 3

    def __repr__(self) -> str:
        return f"StaticModel(perturbation={self.perturbation!r})"

    def fit(self, points_world) -> StaticStructure:
        """P0 = mean of the window (SPEC 2.1)."""
        p = check_points_world(points_world)
        p0 = p.mean(axis=0)
        residual = float(np.sqrt(np.mean(np.sum((p - p0) ** 2, axis=1))))
        return StaticStructure(p0=p0, residual_m=residual)

    def position(self, structure: StaticStructure, q) -> np.ndarray:
        """f(C, q): (3,) for q of shape (dof,), (n, 3) for q of shape (n, dof)."""
        qn, single = _check_q(q, self.dof)
        offset = qn * ONES3 if self.dof == 1 else qn  # l·[1,1,1] or δ
        out = structure.p0 + offset
        return out[0] if single else out

    def jacobian(self, structure: StaticStructure, q) -> np.ndarray:
        """∂f/∂q, shape (3, dof): [1,1,1]ᵀ or I (SPEC 2.1)."""
        _check_q(q, self.dof)
        return ONES3.reshape(3, 1).copy() if self.dof == 1 else np.eye(3)

    def second_derivative(self, structure: StaticStructure, q) -> np.ndarray:
        """∂²f/∂q², shape (3, dof, dof): 0, f is linear in q (SPEC 2.1)."""
        _check_q(q, self.dof)
        return np.zeros((3, self.dof, self.dof))

    def motion_variable(self, structure: StaticStructure, points_world) -> np.ndarray:
        """Inverse kinematics, shape (n, dof): least-squares l = [1,1,1]ᵀ(z − P0)/3, or δ = z − P0."""
        d = check_points_world(points_world) - structure.p0
        return d.mean(axis=1, keepdims=True) if self.dof == 1 else d


class PrismaticModel(_JointModel):
    """Point on a line, f(C, l) = P0 + l·n̂ (SPEC 2.2)."""

    name = "prismatic"
    dof = 1

    def fit(self, points_world) -> PrismaticStructure:
        """Total least squares: P0 = mean, n̂ = first right-singular vector of the centred window.

        n̂ is signed so that l = n̂ᵀ(z − P0) grows over the window (SPEC 2.2).
        Raises DegenerateFitError when all points are identical.
        """
        p = check_points_world(points_world)
        distinct, p0, direction, residual = line_fit(p)  # compiled, the steps above
        if distinct < 2:
            raise DegenerateFitError("line fit needs at least 2 distinct points; all points are identical")
        return PrismaticStructure(p0=p0, direction=direction, residual_m=float(residual))

    def position(self, structure: PrismaticStructure, q) -> np.ndarray:
        """f(C, l) = P0 + l·n̂: (3,) for q (1,), (n, 3) for q (n, 1)."""
        qn, single = _check_q(q, 1)
        out = structure.p0 + qn * structure.direction
        return out[0] if single else out

    def jacobian(self, structure: PrismaticStructure, q) -> np.ndarray:
        """∂f/∂l = n̂, shape (3, 1) (SPEC 2.2)."""
        _check_q(q, 1)
        return structure.direction.reshape(3, 1).copy()

    def second_derivative(self, structure: PrismaticStructure, q) -> np.ndarray:
        """∂²f/∂l², shape (3, 1, 1): 0, a line is straight (SPEC 2.2)."""
        _check_q(q, 1)
        return np.zeros((3, 1, 1))

    def motion_variable(self, structure: PrismaticStructure, points_world) -> np.ndarray:
        """Inverse kinematics l = n̂ᵀ(z − P0), shape (n, 1) (SPEC 2.2)."""
        d = check_points_world(points_world) - structure.p0
        return (d @ structure.direction).reshape(-1, 1)


def _one_angle(q, what: str) -> float:
    """φ of a single motion variable q, shape (1,); ``what`` names the caller in the error."""
    qn, single = _check_q(q, 1)
    if not single:
        raise ValueError(f"{what} takes one q of shape (1,), got {np.shape(q)}")
    return float(qn[0, 0])


class RevoluteModel(_JointModel):
    """Point on a circle, f(C, φ) = (x0 + r cos φ)·v1 + (y0 + r sin φ)·v2 + P0 (SPEC 2.3)."""

    name = "revolute"
    dof = 1

    def fit(self, points_world) -> RevoluteStructure:
        """Plane by SVD of the centred window, then an in-plane circle fit.

        P0 = window mean; v1, v2 = first two right-singular vectors (the normal
        is the last one); circle by Taubin's algebraic fit refined by geometric
        least squares (:func:`stslam.articulation.circle_fit.fit_circle`). v2 (and y0) are
        flipped if needed so that φ grows over the window.

        Raises DegenerateFitError for fewer than 3 distinct points or
        collinear points (SPEC 2.4).
        """
        p = check_points_world(points_world)
        status, distinct, p0, v1, v2, centre_xy, radius, residual = revolute_fit(p)  # compiled, the steps above
        raise_degenerate(status, distinct)
        return RevoluteStructure(p0=p0, v1=v1, v2=v2, centre_xy=centre_xy, radius=float(radius),
                                 residual_m=float(residual))

    def position(self, structure: RevoluteStructure, q) -> np.ndarray:
        """f(C, φ): (3,) for q (1,), (n, 3) for q (n, 1) (SPEC 2.3)."""
        qn, single = _check_q(q, 1)
        phi = qn[:, 0:1]
        x0, y0 = structure.centre_xy
        r = structure.radius
        out = (x0 + r * np.cos(phi)) * structure.v1 + (y0 + r * np.sin(phi)) * structure.v2 + structure.p0
        return out[0] if single else out

    def jacobian(self, structure: RevoluteStructure, q) -> np.ndarray:
        """∂f/∂φ = r(−sin φ·v1 + cos φ·v2), shape (3, 1) (SPEC 2.3)."""
        phi = _one_angle(q, "jacobian")
        r = structure.radius
        return (r * (-np.sin(phi) * structure.v1 + np.cos(phi) * structure.v2)).reshape(3, 1)

    def second_derivative(self, structure: RevoluteStructure, q) -> np.ndarray:
        """∂²f/∂φ² = −r(cos φ·v1 + sin φ·v2), shape (3, 1, 1): towards the centre (SPEC 2.3)."""
        phi = _one_angle(q, "second_derivative")
        r = structure.radius
        return (-r * (np.cos(phi) * structure.v1 + np.sin(phi) * structure.v2)).reshape(3, 1, 1)

    def motion_variable(self, structure: RevoluteStructure, points_world) -> np.ndarray:
        """Inverse kinematics φ = atan2 of the in-plane offset from the centre, unwrapped over time; (n, 1)."""
        p = check_points_world(points_world)
        return revolute_angles(p, structure.p0, structure.v1, structure.v2, structure.centre_xy).reshape(-1, 1)


MODEL_NAMES = ("static", "prismatic", "revolute")
MODELS = {"static": StaticModel(), "prismatic": PrismaticModel(), "revolute": RevoluteModel()}
_CLASSES = {"static": StaticModel, "prismatic": PrismaticModel, "revolute": RevoluteModel}


def get_model(name: str, **options):
    """A model instance by name; ``options`` go to its constructor (e.g. ``perturbation``).

    Raises ValueError for an unknown name, an option the model does not take or a bad option value.
    """
    if name not in _CLASSES:
        raise ValueError(f"name: expected one of {', '.join(MODEL_NAMES)}; got {name!r}")
    try:
        return _CLASSES[name](**options)
    except TypeError:
        raise ValueError(f"options: unknown options of the {name} model: {sorted(options)}") from None
