"""A joint fitted to the pose track of one rigid part: positions and orientations together (SPEC 17, SPEC 2).

A marker on a door or drawer gives, per frame t, its centre p_t (m) and its
orientation R_t (3 × 3), in a frame fixed to the joint's base (a static
camera's, or a reference marker's). The models of SPEC 2, written for a rigid
part (R̄, p̄: the part's pose at q = 0; Q(a, θ) the rotation by θ about a):

    static     R_t = R̄,              p_t = p̄                           (SPEC 2.1)
    prismatic  R_t = R̄,              p_t = p̄ + l_t n̂                    (SPEC 2.2)
    revolute   R_t = Q(a, θ_t) R̄,    p_t = c + Q(a, θ_t)(p̄ − c)         (SPEC 2.3: the hinge is the line c + s a)

A revolute joint turns the marker about the hinge by the very angle its centre
sweeps; a prismatic one does not turn it: the orientation is the evidence the
centre's path alone lacks (a short arc and a line look alike).

Residuals are whitened by the noise of each part (:class:`PoseNoise`): position
r_p = p_t − p̂_t (m) and orientation r_R = log(R_t R̂_tᵀ) (rad, a rotation
vector), χ²_t = r_pᵀ Σ_p⁻¹ r_p + r_Rᵀ Σ_R⁻¹ r_R per frame.

Fits, closed form first:

* static: p̄ the mean, R̄ the chordal mean (the rotation nearest Σ R_t);
* prismatic: R̄ as above; the line by total least squares in whitened
  coordinates (SPEC 2.2), n̂ oriented so that l grows over the track;
* revolute: ω_t = log(R_t R̄ᵀ) lie along a with length θ_t − θ̄ (R̄ the chordal
  mean); a = the principal direction of the whitened ω_t, θ_t = their
  weighted projections; with Q_t = Q(a, θ_t) the positions are linear in the
  hinge point c (2 unknowns across a) and p̄: p_t = (I − Q_t) c + Q_t p̄,
  solved by weighted least squares; then, three times, each θ_t takes a
  Gauss-Newton step on its position and orientation residuals together and
  c, p̄ are solved again (θ_t from the orientation alone errs by its noise, a
  degree, which moves a marker 0.7 m from the hinge by 1 cm). Then every parameter (a, c, R̄, p̄, θ_t) is
  refined together by ``scipy.optimize.least_squares`` (soft-L1 loss: a few
  frames with a wrong pose do not pull the axis). a is oriented so that θ
  grows over the track (SPEC 2.3's convention).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix
from scipy.spatial.transform import Rotation

from stslam.articulation.hinge_axis import axis_basis, axis_from_parameters
from stslam.geometry import rotate_about_axis

MODELS = ("static", "prismatic", "revolute")
# Extra parameters over the per-frame motion variable: R̄ and p̄ (6); a line's direction (2, less p̄'s slide
# along it: 1); a hinge's direction and point (4, with θ's offset taken by R̄: −1).
STRUCTURE_PARAMETERS = {"static": 6, "prismatic": 7, "revolute": 9}
ALTERNATIONS = 3  # closed-form revolute: rounds of θ_t from both residuals, then c and p̄


@dataclass(frozen=True)
class PoseNoise:
    """Noise covariances of one pose: position ``position_cov`` (3, 3) m², orientation ``rotation_cov``
    (3, 3) rad² (a left perturbation, in the reporting frame)."""

    position_cov: np.ndarray
    rotation_cov: np.ndarray

    def whiteners(self) -> tuple[np.ndarray, np.ndarray]:
        """Matrices W_p, W_r (3, 3) with ‖r W‖² = rᵀ Σ⁻¹ r for row vectors r (W = chol(Σ⁻¹))."""
        return (np.linalg.cholesky(np.linalg.inv(self.position_cov)),
                np.linalg.cholesky(np.linalg.inv(self.rotation_cov)))


@dataclass(frozen=True)
class PoseJointFit:
    """A model fitted to a pose track of n frames.

    ``q`` (n,): θ (rad, revolute), l (m, prismatic) or zeros; ``axis`` (3,): hinge axis or slide direction
    (None: static); ``point`` (3,): the hinge point nearest the track's centroid (revolute; for prismatic
    the line's point p̄); residuals (n, 3) m and rad; ``frame_chi2`` (n,) whitened χ² per frame;
    ``n_parameters``: structure parameters plus one q per frame for a moving model.
    """

    model: str
    q: np.ndarray
    axis: np.ndarray | None
    point: np.ndarray | None
    position_residuals: np.ndarray
    rotation_residuals: np.ndarray
    frame_chi2: np.ndarray
    n_parameters: int


def rotation_vectors(R) -> np.ndarray:
    """log of rotations (n, 3, 3) as rotation vectors (n, 3) rad."""
    return Rotation.from_matrix(np.asarray(R, dtype=float).reshape(-1, 3, 3)).as_rotvec()


def chordal_mean(R) -> np.ndarray:
    """The rotation (3, 3) nearest Σ R_t in the Frobenius norm (the chordal L2 mean of rotations (n, 3, 3))."""
    U, _, Vt = np.linalg.svd(np.asarray(R, dtype=float).sum(axis=0))
    return U @ np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))]) @ Vt


def _fit(model, q, axis, point, p, R, p_hat, R_hat, noise, n_frames) -> PoseJointFit:
    W_p, W_r = noise.whiteners()
    r_p = p - p_hat
    r_R = rotation_vectors(np.einsum("nij,nkj->nik", R, R_hat))
    chi2 = np.sum((r_p @ W_p) ** 2, axis=1) + np.sum((r_R @ W_r) ** 2, axis=1)
    extra = 0 if model == "static" else n_frames
    return PoseJointFit(model, q, axis, point, r_p, r_R, chi2, STRUCTURE_PARAMETERS[model] + extra)


def _check(p, R) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(p, dtype=float)
    R = np.asarray(R, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or R.shape != (p.shape[0], 3, 3) or p.shape[0] < 3:
        raise ValueError(f"positions (n, 3) and rotations (n, 3, 3) with n ≥ 3 expected, got {p.shape}, {R.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(R))):
        raise ValueError("positions and rotations must be finite")
    return p, R


def _increasing(values: np.ndarray) -> bool:
    t = np.arange(values.shape[0], dtype=float)
    return float(np.dot(t - t.mean(), values - values.mean())) >= 0.0


def fit_static(p, R, noise: PoseNoise) -> PoseJointFit:
    """Static (module docstring): the mean position and the chordal mean orientation."""
    p, R = _check(p, R)
    n = p.shape[0]
    R_bar = chordal_mean(R)
    return _fit("static", np.zeros(n), None, None, p, R, np.repeat(p.mean(axis=0)[None], n, 0),
                np.repeat(R_bar[None], n, 0), noise, n)


def fit_prismatic(p, R, noise: PoseNoise) -> PoseJointFit:
    """Prismatic (module docstring): whitened total least squares of the line, constant orientation."""
    p, R = _check(p, R)
    n = p.shape[0]
    W_p, _ = noise.whiteners()
    p_bar = p.mean(axis=0)
    white = (p - p_bar) @ W_p
    direction_white = np.linalg.svd(white, full_matrices=False)[2][0]
    direction = np.linalg.solve(W_p.T, direction_white)
    direction /= np.linalg.norm(direction)
    metric = W_p @ W_p.T  # Σ_p⁻¹
    l = (p - p_bar) @ metric @ direction / float(direction @ metric @ direction)  # weighted projection onto the line
    if not _increasing(l):
        direction, l = -direction, -l
    return _fit("prismatic", l, direction, p_bar, p, R, p_bar + np.outer(l, direction),
                np.repeat(chordal_mean(R)[None], n, 0), noise, n)


def _revolute_closed_form(p, R, noise: PoseNoise):
    """(a, θ (n,), c, p̄, R̄) of the closed-form revolute fit (module docstring)."""
    W_p, W_r = noise.whiteners()
    R_bar = chordal_mean(R)
    omega = rotation_vectors(np.einsum("nij,kj->nik", R, R_bar))
    a = np.linalg.solve(W_r.T, np.linalg.svd(omega @ W_r, full_matrices=False)[2][0])
    a /= np.linalg.norm(a)
    metric_r = W_r @ W_r.T
    theta = omega @ metric_r @ a / float(a @ metric_r @ a)
    c, p_bar = _hinge_point(p, a, theta, W_p)
    for _ in range(ALTERNATIONS):  # θ_t from the centre as well (a Gauss-Newton step each), then c and p̄ again
        theta = _theta_step(p, omega, a, theta, c, p_bar, W_p, metric_r)
        c, p_bar = _hinge_point(p, a, theta, W_p)
    return a, theta, c, p_bar, R_bar


def _theta_step(p, omega, a, theta, c, p_bar, W_p, metric_r) -> np.ndarray:
    """One Gauss-Newton step per frame of θ_t on both residuals: ∂p̂/∂θ = a × (p̂ − c), ∂(θ a)/∂θ = a."""
    p_hat, _ = _revolute_prediction(a, c, p_bar, np.eye(3), theta)
    J_p = np.cross(a, p_hat - c)
    metric_p = W_p @ W_p.T
    gradient = np.einsum("ni,ij,nj->n", J_p, metric_p, p - p_hat) + (omega - np.outer(theta, a)) @ metric_r @ a
    curvature = np.einsum("ni,ij,nj->n", J_p, metric_p, J_p) + float(a @ metric_r @ a)
    return theta + gradient / curvature


def _hinge_point(p, a, theta, W_p):
    """c (3,) on the hinge (across a) and p̄ (3,) from p_t = (I − Q_t) c + Q_t p̄, weighted least squares."""
    n = p.shape[0]
    e1, e2 = axis_basis(a)
    Q = np.stack([rotate_about_axis(e, a, theta) for e in np.eye(3)], axis=2)  # (n, 3, 3): Q_t = Q(a, θ_t)
    I_minus_Q = np.eye(3)[None] - Q
    A = np.concatenate([I_minus_Q @ e1[:, None], I_minus_Q @ e2[:, None], Q], axis=2)  # (n, 3, 5)
    A_white = np.einsum("nij,ik->nkj", A, W_p).reshape(3 * n, 5)
    b_white = (p @ W_p).reshape(3 * n)
    x = np.linalg.lstsq(A_white, b_white, rcond=None)[0]
    return x[0] * e1 + x[1] * e2, x[2:]


def _revolute_prediction(a, c, p_bar, R_bar, theta):
    Q = np.stack([rotate_about_axis(e, a, theta) for e in np.eye(3)], axis=2)
    return c + np.einsum("nij,j->ni", Q, p_bar - c), Q @ R_bar


def fit_revolute(p, R, noise: PoseNoise, refine: bool = True, loss_scale: float = 3.0) -> PoseJointFit:
    """Revolute (module docstring): closed form, then (``refine``) all parameters together with a soft-L1
    loss of scale ``loss_scale`` (whitened units)."""
    p, R = _check(p, R)
    n = p.shape[0]
    a, theta, c, p_bar, R_bar = _revolute_closed_form(p, R, noise)
    if refine:
        a, theta, c, p_bar, R_bar = _refine_revolute(p, R, noise, a, theta, c, p_bar, R_bar, loss_scale)
    if not _increasing(theta):
        a, theta = -a, -theta
    p_hat, R_hat = _revolute_prediction(a, c, p_bar, R_bar, theta)
    centroid = p.mean(axis=0)
    point = c + float((centroid - c) @ a) * a
    return _fit("revolute", theta, a, point, p, R, p_hat, R_hat, noise, n)


def _refine_revolute(p, R, noise, a0, theta0, c0, p_bar0, R_bar0, loss_scale):
    n = p.shape[0]
    W_p, W_r = noise.whiteners()
    e1, e2 = axis_basis(a0)

    def unpack(x):
        c, a = axis_from_parameters(x[:4], c0, a0, e1, e2)
        R_bar = Rotation.from_rotvec(x[4:7]).as_matrix() @ R_bar0
        return a, c, x[7:10], R_bar, x[10:]

    def residuals(x):
        a, c, p_bar, R_bar, theta = unpack(x)
        p_hat, R_hat = _revolute_prediction(a, c, p_bar, R_bar, theta)
        r_R = rotation_vectors(np.einsum("nij,nkj->nik", R, R_hat))
        return np.concatenate([(p - p_hat) @ W_p, r_R @ W_r], axis=1).reshape(-1)

    sparsity = lil_matrix((6 * n, 10 + n), dtype=int)
    sparsity[:, :10] = 1
    for k in range(n):
        sparsity[6 * k:6 * k + 6, 10 + k] = 1
    x0 = np.concatenate([np.zeros(7), p_bar0, theta0])
    result = least_squares(residuals, x0, jac_sparsity=sparsity, loss="soft_l1", f_scale=loss_scale,
                           x_scale=np.concatenate([[0.05, 0.05, 0.05, 0.05, 0.02, 0.02, 0.02, 0.05, 0.05, 0.05],
                                                   np.full(n, 0.05)]), max_nfev=50)
    a, c, p_bar, R_bar, theta = unpack(result.x)
    c = c - float(c @ a) * a  # the point of the hinge across a (its slide along a is free)
    return a, theta, c, p_bar, R_bar


def fit_pose_model(model: str, p, R, noise: PoseNoise, refine: bool = True) -> PoseJointFit:
    """The fit of ``model`` (one of :data:`MODELS`) to positions (n, 3) and rotations (n, 3, 3)."""
    if model == "static":
        return fit_static(p, R, noise)
    if model == "prismatic":
        return fit_prismatic(p, R, noise)
    if model == "revolute":
        return fit_revolute(p, R, noise, refine=refine)
    raise ValueError(f"model: expected one of {', '.join(MODELS)}; got {model!r}")
