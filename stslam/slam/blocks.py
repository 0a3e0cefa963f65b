"""Landmark blocks: how one landmark lives in the SLAM state (SPEC 6).

A block is the part of the state vector that belongs to one landmark. Each
kind answers three questions for the core (:mod:`stslam.slam.core`):

* ``initial(m_world)`` — the block from a first world-frame point m: its mean
  x_b (k,), the Jacobian D = ∂x_b/∂m (k, 3) that carries m's covariance (and
  its cross-covariance with the robot) into the block, and an independent
  prior covariance (k, k) for what one point cannot tell (e.g. a velocity);
* ``transition(dt)`` — the block's linear prediction x_b ← F x_b + noise: (F (k, k)
  or None for identity, Q (k, k) or None for none); blocks with equal
  transitions are predicted together. Moving blocks take F and Q from their
  :class:`~stslam.kalman.temporal.MotionModel`, which computes them once per δt;
* ``position(x_b)`` — the landmark's world position m (3,) and ∂m/∂x_b (3, k).

Blocks are immutable and hold only parameters (and, for articulated blocks,
the model and structure); the numbers live in the core's x and P.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stslam.articulation.correction import corrected_position, correction_size, member_corrected_position
from stslam.articulation.models import PrismaticModel, RevoluteModel
from stslam.kalman.temporal import MotionModel

EYE3 = np.eye(3)


@dataclass(frozen=True)
class StaticPointBlock:
    """A static 3D point m (SPEC 6.1), optionally a random walk: m_t = m_{t−1} + N(0, σ²δt I₃).

    ``sigma_walk`` in m/√s (m per frame for δt = 1); 0 gives the textbook
    static landmark.
    """

    sigma_walk: float = 0.0
    size: int = 3

    def initial(self, m_world):
        return np.asarray(m_world, dtype=float).copy(), EYE3.copy(), np.zeros((3, 3))

    def transition(self, dt: float):
        if self.sigma_walk == 0.0:
            return None, None
        return None, (self.sigma_walk**2 * dt) * EYE3

    def position(self, x_b):
        return x_b, EYE3


@dataclass(frozen=True)
class ConstantVelocityPointBlock:
    """A 3D point moving with constant velocity (SPEC 6.2, Dyn. SLAM).

    Block [m (3), ṁ (3)]: m_t = m_{t−1} + δt ṁ, i.e. m_t = m_{t−1} + (m_{t−1} −
    m_{t−2}) for δt = 1; white acceleration noise of std ``sigma_acc`` (m/s²)
    per axis, Q = SPEC 3's order-1 noise ⊗ I₃. The velocity starts at 0 with
    std ``sigma_v0`` (m/s) per axis.
    """

    sigma_acc: float
    sigma_v0: float
    size: int = 6
    motion: MotionModel = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "motion", MotionModel(1, 3, self.sigma_acc))  # SPEC 3, order 1, per axis

    def initial(self, m_world):
        x_b = np.concatenate([np.asarray(m_world, dtype=float), np.zeros(3)])
        D = np.vstack([EYE3, np.zeros((3, 3))])
        prior = np.zeros((6, 6))
        prior[3:, 3:] = self.sigma_v0**2 * EYE3
        return x_b, D, prior

    def transition(self, dt: float):
        return self.motion.matrices(dt)

    def position(self, x_b):
        return x_b[:3], np.hstack([EYE3, np.zeros((3, 3))])


@dataclass(frozen=True, eq=False)
class ArticulatedBlock:
    """A landmark on a known articulation: m = f(C, q) with motion state X (SPEC 2, 3, 6.3).

    X = [q, q⁽¹⁾, …, q⁽ᵏ⁾] stacked per derivative (each of length dof), evolving as
    X_{t+1} = (A ⊗ I_dof) X_t + (B ⊗ I_dof) η, η ~ N(0, σ_η² I) (SPEC 3);
    ∂m/∂X = [∂f/∂q, 0, …] (SPEC 5.3). From a first point m, q is the model's
    inverse kinematics and ∂q/∂m the pseudo-inverse of ∂f/∂q (exact on the
    model's curve: n̂ᵀ for a line, (∂f/∂φ)ᵀ/r² for a circle, [1,1,1]/3 for the
    static perturbation); the derivatives start at 0 with std ``sigma_rate0``
    (units of q per second, per order).

    Parameters
    ----------
    model : articulation model (``stslam.articulation.models``)
    structure : its structure C
    order : int
        Temporal order k (the paper uses 1).
    sigma_eta : float
        Std of η, the (k+1)-th derivative of q (m/s^(k+1) or rad/s^(k+1)).
    sigma_rate0 : float
        Prior std of each derivative of q at initialisation.
    sigma_slip : float
        Std of the slip's random walk (m/√s); 0 (the default): no slip, m = f(C, q).
        Otherwise the block ends with a slip δ (3,), world frame, and m = f(C, q) + δ,
        δ_t = δ_{t−1} + N(0, σ_slip² δt I₃), starting at 0: a feature tracker
        follows a texture patch, not a physical point, and on a part that turns
        or slides the patch's appearance changes, so the tracked point creeps
        over the part's surface (frame-to-frame template drift: Matthews, Ishikawa
        & Baker 2004, "The template update problem"). Its error is then
        correlated in time and shared by the part's points: white R cannot
        carry it, a fixed C turns it into robot error.
    """

    model: object
    structure: object
    order: int
    sigma_eta: float
    sigma_rate0: float
    sigma_slip: float = 0.0
    motion: MotionModel = field(init=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "motion", MotionModel(self.order, self.model.dof, self.sigma_eta))  # SPEC 3
        object.__setattr__(self, "_padded_matrices", {})  # δt → (F, Q) of the state with its tail

    @property
    def dof(self) -> int:
        return self.model.dof

    @property
    def motion_size(self) -> int:
        """Length of the motion state X = [q, q⁽¹⁾, …, q⁽ᵏ⁾]; the slip, if any, follows it."""
        return self.dof * (self.order + 1)

    @property
    def size(self) -> int:
        return self.motion_size + (3 if self.sigma_slip > 0.0 else 0)

    def initial(self, m_world):
        m = np.asarray(m_world, dtype=float).reshape(1, 3)
        q = self.model.motion_variable(self.structure, m)[0]
        J = self.model.jacobian(self.structure, q)
        x_b = np.zeros(self.size)
        x_b[: self.dof] = q
        D = np.zeros((self.size, 3))
        D[: self.dof] = np.linalg.pinv(J)
        prior = np.zeros((self.size, self.size))
        n = self.motion_size
        prior[self.dof:n, self.dof:n] = self.sigma_rate0**2 * np.eye(n - self.dof)
        return x_b, D, prior  # the slip starts at 0: the first point is on the structure

    def transition(self, dt: float):
        if self.sigma_slip == 0.0:
            return self.motion.matrices(dt)
        return self._padded_transition(dt, self.sigma_slip**2 * dt)  # random walk of the slip

    def _padded_transition(self, dt: float, tail_variance: float):
        """F, Q of the motion state followed by a tail (the slip, a structure correction) that stays
        as it is, with ``tail_variance`` I added per step; kept per δt."""
        if dt not in self._padded_matrices:
            F, Q = self.motion.matrices(dt)
            n = self.motion_size
            F_all, Q_all = np.eye(self.size), np.zeros((self.size, self.size))
            F_all[:n, :n], Q_all[:n, :n] = F, Q
            Q_all[n:, n:] = tail_variance * np.eye(self.size - n)
            F_all.flags.writeable = Q_all.flags.writeable = False
            self._padded_matrices[dt] = (F_all, Q_all)
        return self._padded_matrices[dt]

    def position(self, x_b):
        q = x_b[: self.dof]
        dm_dx = np.zeros((3, self.size))
        dm_dx[:, : self.dof] = self.model.jacobian(self.structure, q)
        m = self.model.position(self.structure, q)
        if self.sigma_slip == 0.0:
            return m, dm_dx
        dm_dx[:, self.motion_size:] = EYE3
        return m + x_b[self.motion_size:], dm_dx


@dataclass(frozen=True, eq=False)
class CorrectedArticulatedBlock(ArticulatedBlock):
    """An articulated landmark whose structure correction δ is in the state: [X, δ] (SPEC 6.3(b)).

    m = f(C ⊕ δ, q) (:func:`stslam.articulation.correction.corrected_position`);
    δ is constant (F = I, no process noise), so every observation refines it.
    ``founder_structure`` set: a body member's view of its founder's block
    (:mod:`stslam.slam.bodies`), the same size, on its own structure in the founder's q; it reads the
    part of δ that moves the joint, not the founder's own offset
    (:func:`~stslam.articulation.correction.member_corrected_position`). ``consider``: δ is a consider
    parameter (``structure_state: consider``, the Schmidt–Kalman filter): never updated, its covariance
    carried into every innovation and gain. ``member_offset``: a member view whose block also reads the
    error ε (3,) of the member's own offset, after the founder's block
    (:class:`~stslam.slam.bodies.state.BodySlamState` keeps it, a consider parameter like δ).
    """

    founder_structure: object = None
    consider: bool = False
    member_offset: bool = False

    @property
    def frozen(self) -> tuple:
        """Block entries the updates leave as they are: δ when it is a consider parameter."""
        return tuple(range(self.motion_size, self.size)) if self.consider else ()

    def __post_init__(self):
        if self.sigma_slip != 0.0:  # its size, transition and reading have no slip
            raise ValueError(f"sigma_slip: a corrected block has no slip, got {self.sigma_slip}")
        if self.member_offset and self.founder_structure is None:
            raise ValueError("member_offset: only a member's view (founder_structure set) reads an offset error")
        super().__post_init__()

    @property
    def size(self) -> int:
        return self.motion_size + correction_size(self.model.name) + (3 if self.member_offset else 0)

    def initial(self, m_world):
        raise ValueError("a corrected block is made from an articulated block (SlamState.replace_block)")

    def transition(self, dt: float):
        return self._padded_transition(dt, 0.0)  # δ is constant

    def position(self, x_b):
        q, k = x_b[: self.dof], self.motion_size
        dm_dx = np.zeros((3, self.size))
        if self.founder_structure is None:
            m, dm_dq, dm_ddelta = corrected_position(self.model.name, self.structure, float(q[0]), x_b[k:])
        elif not self.member_offset:  # SPEC 13: a member reads the joint's part of its founder's δ
            m, dm_dq, dm_ddelta = member_corrected_position(self.model.name, self.founder_structure,
                                                            self.structure, float(q[0]), x_b[k:])
        else:  # and its own offset's error ε, the block's last three entries
            end = self.size - 3
            m, dm_dq, dm_ddelta, dm_dx[:, end:] = member_corrected_position(
                self.model.name, self.founder_structure, self.structure, float(q[0]), x_b[k:end], x_b[end:])
            dm_dx[:, 0], dm_dx[:, k:end] = dm_dq, dm_ddelta
            return m, dm_dx
        dm_dx[:, 0], dm_dx[:, k:] = dm_dq, dm_ddelta
        return m, dm_dx

    def member_view(self, structure, member_offset: bool = False):
        """A member's block on its own ``structure``, reading this block's q and its joint's δ (and the
        offset error ε after them, ``member_offset``)."""
        return CorrectedArticulatedBlock(self.model, structure, self.order, self.sigma_eta, self.sigma_rate0,
                                         founder_structure=self.structure, consider=self.consider,
                                         member_offset=member_offset)


@dataclass(frozen=True)
class OffsetErrorBlock:
    """A body member's offset error ε (3,) held as a consider parameter (SPEC 13, Schmidt–Kalman): constant,
    never updated; not a landmark, only read through the member's view
    (:class:`CorrectedArticulatedBlock` with ``member_offset``)."""

    size: int = 3
    frozen: tuple = (0, 1, 2)

    def transition(self, dt: float):
        return None, None


def stack_key(block):
    """Blocks with the same key have their positions computed together (:func:`stacked_positions`): static
    points, constant-velocity points, and plain articulated blocks of a prismatic or revolute joint of one size.
    None for any other block (a corrected one, another model), which takes its own ``position``."""
    kind = type(block)
    if kind is StaticPointBlock or kind is ConstantVelocityPointBlock:
        return (kind,)
    if kind is ArticulatedBlock and type(block.model) in (PrismaticModel, RevoluteModel):
        return kind, type(block.model), block.size, block.motion_size
    return None


def stacked_positions(blocks, x_bs) -> tuple[np.ndarray, np.ndarray | None]:
    """``position`` of k blocks with one :func:`stack_key` at their means x_bs (k, size): m (k, 3) and ∂m/∂x_b
    (k, 3, size), or None for static points (∂m/∂x_b = I). Each row has the numbers of the block's own
    ``position``: the same IEEE operations on each element (SPEC 2.2, 2.3, 6.1, 6.2)."""
    first, k = blocks[0], len(blocks)
    if type(first) is StaticPointBlock:
        return x_bs, None
    if type(first) is ConstantVelocityPointBlock:
        return x_bs[:, :3], np.broadcast_to(np.hstack([EYE3, np.zeros((3, 3))]), (k, 3, 6))
    q = x_bs[:, :1]  # (k, 1): each block's q
    dm_dx = np.zeros((k, 3, first.size))
    if type(first.model) is PrismaticModel:  # f = P0 + l·n̂, ∂f/∂l = n̂
        direction = np.array([b.structure.direction for b in blocks])
        m = np.array([b.structure.p0 for b in blocks]) + q * direction
        dm_dx[:, :, 0] = direction
    else:  # f = (x0 + r cos φ)·v1 + (y0 + r sin φ)·v2 + P0, ∂f/∂φ = r(−sin φ·v1 + cos φ·v2)
        v1, v2 = np.array([b.structure.v1 for b in blocks]), np.array([b.structure.v2 for b in blocks])
        centre = np.array([b.structure.centre_xy for b in blocks])
        r = np.array([[b.structure.radius] for b in blocks], dtype=float)
        m = ((centre[:, 0:1] + r * np.cos(q)) * v1 + (centre[:, 1:2] + r * np.sin(q)) * v2
             + np.array([b.structure.p0 for b in blocks]))
        dm_dx[:, :, 0] = r * (-np.sin(q) * v1 + np.cos(q) * v2)
    if first.sigma_slip != 0.0:  # m = f(C, q) + δ
        m = m + x_bs[:, first.motion_size:]
        dm_dx[:, :, first.motion_size:] = EYE3
    return m, dm_dx
