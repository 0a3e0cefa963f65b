"""Residuals of the back end's factors with analytic Jacobians, and their gtsam CustomFactors (SPEC 14).

Every variable is a plain vector: a robot pose (x m, y m, θ rad), or one
landmark block's state at one frame (:mod:`stslam.slam.blocks`: a point, a
point and its velocity, an articulated motion state). Each ``*_residual``
function returns the unwhitened error e and its Jacobians with respect to the
factor's variables, in the factor's key order; gtsam whitens with the
factor's noise model and minimises Σ ‖e‖²_Σ.

* prior: e = x − x̄ (θ difference wrapped for poses);
* odometry (SPEC 5.1): e = x_{k+1} ⊖ g(x_k, u, δt), ∂e/∂x_k = −G, ∂e/∂x_{k+1} = I;
* observation (SPEC 5.2, 5.3): e = R(θ)ᵀ(m(x_b) − [x, y, 0]ᵀ) − z with
  ∂e/∂pose = H_pose, ∂e/∂x_b = H_m ∂m/∂x_b;
* observation with the structure a variable (:mod:`stslam.graph.structure`):
  e = h(pose, f(C ⊕ δ, q)) − z, Jacobians (H_pose, H_m ∂f/∂X, H_m ∂f/∂δ);
* linear relation: e = x_to − F x_from − c. With c = 0 it is a block's
  transition between two of its frames (SPEC 3's X_{t+1} = A X_t + B η,
  Dyn. SLAM's constant velocity, a random walk); with F = J, c = x̄_new − J x̄_old
  it carries a block conversion (x_new = g(x_old) linearised);
* selected prior: e = S (x − x̄), S picking the components a block's first
  observation cannot tell (e.g. a velocity).
"""

from __future__ import annotations

import numpy as np

from stslam.graph.structure import corrected_position
from stslam.robot.motion import motion_jacobians, move, wrap_angle
from stslam.robot.sensor import observation_jacobians, observe

EYE3 = np.eye(3)


def pose_prior_residual(pose, pose_bar):
    """e = pose − pose̅ with θ wrapped; ∂e/∂pose = I."""
    e = np.asarray(pose, dtype=float) - np.asarray(pose_bar, dtype=float)
    e[2] = wrap_angle(e[2])
    return e, [EYE3.copy()]


def selected_prior_residual(x, x_bar, rows):
    """e = x[rows] − x̄[rows]; ∂e/∂x = S (len(rows), k), the selection matrix."""
    x = np.asarray(x, dtype=float)
    S = np.eye(x.size)[rows]
    return S @ (x - np.asarray(x_bar, dtype=float)), [S]


def odometry_residual(pose_from, pose_to, control_vw, dt: float):
    """e = x_{k+1} − g(x_k, u, δt), θ wrapped (SPEC 5.1); Jacobians (−G, I)."""
    G, _ = motion_jacobians(pose_from, control_vw, dt)
    e = np.asarray(pose_to, dtype=float) - move(pose_from, control_vw, dt)
    e[2] = wrap_angle(e[2])
    return e, [-G, EYE3.copy()]


def observation_residual(pose, x_b, block, z_robot):
    """e = h(pose, m(x_b)) − z (SPEC 5.2); Jacobians (H_pose, H_m ∂m/∂x_b) (SPEC 5.3)."""
    m, dm_dx = block.position(np.asarray(x_b, dtype=float))
    H_pose, H_m = observation_jacobians(pose, m)
    return observe(pose, m) - np.asarray(z_robot, dtype=float), [H_pose, H_m @ dm_dx]


def structured_observation_residual(pose, x_b, delta, block, z_robot):
    """e = h(pose, f(C ⊕ δ, q)) − z; Jacobians (H_pose, H_m ∂f/∂X, H_m ∂f/∂δ) (SPEC 5.2, 5.3)."""
    x_b = np.asarray(x_b, dtype=float)
    m, dm_dq, dm_ddelta = corrected_position(block.model.name, block.structure, float(x_b[0]), delta)
    H_pose, H_m = observation_jacobians(pose, m)
    dm_dx = np.zeros((3, x_b.size))
    dm_dx[:, 0] = dm_dq
    return observe(pose, m) - np.asarray(z_robot, dtype=float), [H_pose, H_m @ dm_dx, H_m @ dm_ddelta]


def linear_residual(x_from, x_to, F, c):
    """e = x_to − F x_from − c; Jacobians (−F, I)."""
    F = np.atleast_2d(np.asarray(F, dtype=float))
    e = np.asarray(x_to, dtype=float) - F @ np.asarray(x_from, dtype=float) - c
    return e, [-F, np.eye(F.shape[0])]


# ---------------------------------------------------------------- gtsam side

def gaussian(cov, floor_sigma: float):
    """gtsam noise model of covariance ``cov`` + floor² I (the floor regularises a singular one)."""
    import gtsam

    cov = np.atleast_2d(np.asarray(cov, dtype=float))
    cov = 0.5 * (cov + cov.T) + floor_sigma**2 * np.eye(cov.shape[0])
    return gtsam.noiseModel.Gaussian.Covariance(cov)


def custom_factor(noise, keys, residual):
    """A gtsam CustomFactor on vector variables ``keys``: ``residual(*values) -> (e, [J per key])``."""
    import gtsam

    def error(this, values, jacobians):
        e, J = residual(*(values.atVector(key) for key in this.keys()))
        if jacobians is not None:
            for i, block in enumerate(J):
                jacobians[i] = block
        return e

    return gtsam.CustomFactor(noise, list(keys), error)


def pose_prior_factor(key, pose_bar, cov, floor_sigma):
    pose_bar = np.asarray(pose_bar, dtype=float).copy()
    return custom_factor(gaussian(cov, floor_sigma), [key], lambda p: pose_prior_residual(p, pose_bar))


def selected_prior_factor(key, x_bar, rows, cov, floor_sigma):
    x_bar, rows = np.asarray(x_bar, dtype=float).copy(), list(rows)
    return custom_factor(gaussian(cov, floor_sigma), [key], lambda x: selected_prior_residual(x, x_bar, rows))


def odometry_factor(key_from, key_to, control_vw, dt, cov, floor_sigma):
    u = np.asarray(control_vw, dtype=float).copy()
    return custom_factor(gaussian(cov, floor_sigma), [key_from, key_to],
                         lambda a, b: odometry_residual(a, b, u, dt))


def huber(noise, k: float):
    """``noise`` with a Huber kernel: whitened errors up to ‖e‖ = k count fully, beyond it with weight k/‖e‖."""
    import gtsam

    return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Huber.Create(float(k)), noise)


def observation_factor(pose_key, block_key, block, z_robot, R, floor_sigma, huber_k=None):
    z = np.asarray(z_robot, dtype=float).copy()
    noise = gaussian(R, floor_sigma)
    return custom_factor(noise if huber_k is None else huber(noise, huber_k), [pose_key, block_key],
                         lambda p, x: observation_residual(p, x, block, z))


def structured_observation_factor(pose_key, block_key, structure_key, block, z_robot, R, floor_sigma, huber_k=None):
    z = np.asarray(z_robot, dtype=float).copy()
    noise = gaussian(R, floor_sigma)
    return custom_factor(noise if huber_k is None else huber(noise, huber_k), [pose_key, block_key, structure_key],
                         lambda p, x, d: structured_observation_residual(p, x, d, block, z))


def linear_factor(key_from, key_to, F, c, cov, floor_sigma):
    F, c = np.array(F, dtype=float), np.array(c, dtype=float)
    return custom_factor(gaussian(cov, floor_sigma), [key_from, key_to], lambda a, b: linear_residual(a, b, F, c))


def loose_prior_factor(key, x_bar, sigma):
    """e = x − x̄ with covariance σ² I: keeps a variable determined where nothing else does."""
    x_bar = np.asarray(x_bar, dtype=float).copy()
    rows = np.arange(x_bar.size)
    return selected_prior_factor(key, x_bar, rows, sigma**2 * np.eye(x_bar.size), 0.0)
