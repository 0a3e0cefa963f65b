"""Each factor's analytic Jacobians against central differences (SPEC 14), and the gtsam wrapping."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.articulation.models import PrismaticStructure, get_model
from stslam.graph import factors
from stslam.sim.worlds import revolute_structure
from stslam.slam.blocks import ArticulatedBlock, ConstantVelocityPointBlock, StaticPointBlock

STEP = 1e-6
TOL = 1e-6


def numerical(fn, args, which):
    """Central-difference Jacobian of fn(*args)[0] with respect to args[which]."""
    x = np.asarray(args[which], dtype=float)
    cols = []
    for i in range(x.size):
        d = np.zeros_like(x)
        d[i] = STEP
        hi = list(args); hi[which] = x + d
        lo = list(args); lo[which] = x - d
        cols.append((fn(*hi)[0] - fn(*lo)[0]) / (2 * STEP))
    return np.column_stack(cols)


def check(fn, args, n_vars):
    _, J = fn(*args)
    assert len(J) == n_vars
    for which in range(n_vars):
        np.testing.assert_allclose(J[which], numerical(fn, args, which), atol=TOL, rtol=0)


BLOCKS = {
    "static": (StaticPointBlock(0.01), np.array([1.0, 2.0, 0.5])),
    "constant_velocity": (ConstantVelocityPointBlock(0.01, 0.1), np.array([1.0, 2.0, 0.5, 0.1, -0.2, 0.05])),
    "prismatic": (ArticulatedBlock(get_model("prismatic"),
                                   PrismaticStructure(np.array([1.0, 1.5, 0.4]), np.array([0.6, 0.8, 0.0]), 0.0),
                                   1, 0.01, 0.01), np.array([0.3, 0.02])),
    "revolute": (ArticulatedBlock(get_model("revolute"),
                                  revolute_structure([2.0, 1.0, 0.5], [0.0, 0.2, 1.0], [1.0, 0.0, 0.0], 0.7),
                                  2, 0.1, 0.05), np.array([0.8, 0.1, -0.01])),
}


@pytest.mark.parametrize("name", sorted(BLOCKS))
@pytest.mark.parametrize("pose", [[0.2, -0.3, 0.4], [3.0, 1.0, -2.9]])
def test_observation_jacobians(name, pose):
    block, x_b = BLOCKS[name]
    z = np.array([0.5, -0.1, 0.3])
    check(lambda p, x: factors.observation_residual(p, x, block, z), [np.array(pose), x_b], 2)


@pytest.mark.parametrize("control", [[0.5, 0.3], [0.5, 0.0], [0.2, -1.2]])
def test_odometry_jacobians_both_branches(control):
    u = np.array(control)
    fn = lambda a, b: factors.odometry_residual(a, b, u, 0.5)  # noqa: E731
    check(fn, [np.array([1.0, 2.0, 0.3]), np.array([1.2, 2.1, 0.45])], 2)


def test_odometry_residual_wraps_the_heading():
    e, _ = factors.odometry_residual(np.array([0.0, 0.0, 3.1]), np.array([0.0, 0.0, -3.1]), np.zeros(2), 1.0)
    assert abs(e[2] - (2 * np.pi - 6.2)) < 1e-12


def test_linear_prior_and_selected_prior_jacobians():
    rng = np.random.default_rng(3)
    F, c = rng.normal(size=(3, 2)), rng.normal(size=3)
    check(lambda a, b: factors.linear_residual(a, b, F, c), [rng.normal(size=2), rng.normal(size=3)], 2)
    check(lambda p: factors.pose_prior_residual(p, np.array([1.0, 2.0, 0.1])), [np.array([1.1, 1.9, 0.3])], 1)
    check(lambda x: factors.selected_prior_residual(x, np.zeros(4), [1, 3]), [rng.normal(size=4)], 1)


def test_custom_factor_error_is_half_the_whitened_square():
    gtsam = pytest.importorskip("gtsam")
    block, x_b = BLOCKS["revolute"]
    pose, z, R = np.array([0.2, -0.3, 0.4]), np.array([0.5, -0.1, 0.3]), np.diag([0.01, 0.02, 0.03])
    factor = factors.observation_factor(1, 2, block, z, R, 0.0)
    values = gtsam.Values()
    values.insert(1, pose)
    values.insert(2, x_b)
    e, J = factors.observation_residual(pose, x_b, block, z)
    assert factor.error(values) == pytest.approx(0.5 * e @ np.linalg.solve(R, e), rel=1e-12)
    A, b = factor.linearize(values).jacobian()
    # gtsam whitens: A = W [J_pose, J_b], b = −W e with Wᵀ W = R⁻¹
    np.testing.assert_allclose(A.T @ A, np.hstack(J).T @ np.linalg.solve(R, np.hstack(J)), atol=1e-9)
    np.testing.assert_allclose(A.T @ b, -np.hstack(J).T @ np.linalg.solve(R, e), atol=1e-9)


@pytest.mark.parametrize("name", ["prismatic", "revolute"])
@pytest.mark.parametrize("scale", [0.0, 1e-8, 0.2])  # at the fit, inside the series branch, a real correction
def test_structured_observation_jacobians(name, scale):
    block, x_b = BLOCKS[name]
    delta = scale * np.random.default_rng(5).normal(size=6 if name == "revolute" else 4)
    z = np.array([0.5, -0.1, 0.3])
    check(lambda p, x, d: factors.structured_observation_residual(p, x, d, block, z),
          [np.array([0.2, -0.3, 0.4]), x_b, delta], 3)


@pytest.mark.parametrize("name", ["prismatic", "revolute"])
def test_zero_correction_is_the_fitted_structure(name):
    block, x_b = BLOCKS[name]
    pose, z = np.array([0.2, -0.3, 0.4]), np.array([0.5, -0.1, 0.3])
    e, J = factors.observation_residual(pose, x_b, block, z)
    e_s, J_s = factors.structured_observation_residual(pose, x_b, np.zeros(6 if name == "revolute" else 4), block, z)
    np.testing.assert_allclose(e_s, e, atol=1e-12)
    np.testing.assert_allclose(J_s[1], J[1], atol=1e-12)


def test_structure_corrections_move_the_line_and_the_circle_as_stated():
    from stslam.graph.structure import across, corrected_position

    block, _ = BLOCKS["prismatic"]
    e1, e2 = across(block.structure.direction)
    m, _, _ = corrected_position("prismatic", block.structure, 0.0, [0.1, -0.2, 0.0, 0.0])
    np.testing.assert_allclose(m, block.structure.p0 + 0.1 * e1 - 0.2 * e2, atol=1e-12)
    revolute, _ = BLOCKS["revolute"]
    centre, radius = revolute.structure.centre_world, revolute.structure.radius
    for phi in (0.0, 1.0, 2.5):  # tilted and resized, every point stays on a circle of radius r + ρ about c₀ + c
        m, _, _ = corrected_position("revolute", revolute.structure, phi, [0.1, 0.0, -0.1, 0.05, 0.02, 0.1])
        assert np.linalg.norm(m - centre - [0.1, 0.0, -0.1]) == pytest.approx(radius + 0.1, abs=1e-12)
