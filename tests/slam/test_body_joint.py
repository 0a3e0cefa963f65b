"""Articulated bodies (SPEC 13): member kinematics, Jacobians, member structures, the rigidity test."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import chi2

from stslam.articulation.hinge_axis import AxisTolerance
from stslam.slam.bodies.joint import (BodyJoint, axes_agree, joint_of, member_jacobian, member_offset,
                                      member_position, member_structure, rigidity_test)
from stslam.articulation.models import get_model
from stslam.geometry import rotation_about_axis

HINGE = BodyJoint("revolute", np.array([0.4, 5.0, 1.2]), np.array([0.0, 0.0, -1.0]))
SLIDE = BodyJoint("prismatic", np.zeros(3), np.array([0.0, 1.0, 0.0]))


def test_revolute_member_turns_about_the_axis_and_keeps_its_distance():
    p_ref = np.array([1.1, 5.0, 0.3])
    p = member_position(HINGE, p_ref, 0.2, 0.2 + np.pi / 2)
    # A quarter turn about −z from +x of the hinge: towards −y, same height, same radius.
    np.testing.assert_allclose(p, [0.4, 5.0 - 0.7, 0.3], atol=1e-12)
    np.testing.assert_allclose(member_position(HINGE, p_ref, 0.2, 0.2), p_ref, atol=1e-15)
    expected = HINGE.point + rotation_about_axis(HINGE.direction, 0.7) @ (p_ref - HINGE.point)
    np.testing.assert_allclose(member_position(HINGE, p_ref, 0.1, 0.8), expected, atol=1e-12)


def test_prismatic_member_slides_along_the_direction():
    p = member_position(SLIDE, [4.0, 0.0, 0.85], 0.1, 0.4)
    np.testing.assert_allclose(p, [4.0, 0.3, 0.85])


@pytest.mark.parametrize("joint", [HINGE, SLIDE, BodyJoint("revolute", np.array([2.3, 0.0, 0.1]),
                                                           np.array([-1.0, 0.0, 0.0]))])
@pytest.mark.parametrize("q", [-0.4, 0.0, 0.9, 2.5])
def test_member_jacobian_matches_numerical_differences(joint, q):
    p_ref = np.array([1.3, 4.2, 0.7])
    h = 1e-6
    numeric = (member_position(joint, p_ref, 0.3, q + h) - member_position(joint, p_ref, 0.3, q - h)) / (2 * h)
    np.testing.assert_allclose(member_jacobian(joint, p_ref, 0.3, q)[:, 0], numeric, atol=1e-8)


@pytest.mark.parametrize("joint", [HINGE, SLIDE])
def test_member_structure_is_the_member_on_the_body_q(joint):
    """f(C_i, q) and ∂f/∂q of the SPEC 2 model on the member's structure are p_i(q) and ∂p_i/∂q."""
    p_zero = np.array([1.0, 5.0, 1.0])
    structure = member_structure(joint, p_zero)
    model = get_model(joint.model_name)
    for q in (-0.3, 0.0, 0.6, 1.4):
        np.testing.assert_allclose(model.position(structure, np.array([q])),
                                   member_position(joint, p_zero, 0.0, q), atol=1e-12)
        np.testing.assert_allclose(model.jacobian(structure, np.array([q])),
                                   member_jacobian(joint, p_zero, 0.0, q), atol=1e-12)
    # Inverse kinematics of a point of the member's path gives back the body's q.
    point = member_position(joint, p_zero, 0.0, 0.8)
    assert model.motion_variable(structure, point.reshape(1, 3))[0, 0] == pytest.approx(0.8)


def test_member_structure_refuses_a_point_on_the_axis():
    with pytest.raises(ValueError, match="p_zero: expected a point at least"):
        member_structure(HINGE, [0.4, 5.0, 0.1])


def test_member_offset_takes_the_points_back_to_q_zero():
    rng = np.random.default_rng(3)
    p_zero = np.array([1.1, 5.0, 1.75])
    qs = np.linspace(0.0, 1.5, 40)
    points = np.array([member_position(HINGE, p_zero, 0.0, q) for q in qs]) + 0.01 * rng.standard_normal((40, 3))
    np.testing.assert_allclose(member_offset(HINGE, points, qs), p_zero, atol=0.01)
    with pytest.raises(ValueError, match="points, qs"):
        member_offset(HINGE, points, qs[:-1])


def test_joint_of_a_fitted_structure_and_agreement():
    revolute = get_model("revolute")
    qs = np.linspace(0.0, 1.2, 15)
    points = np.array([member_position(HINGE, [1.1, 5.0, 1.2], 0.0, q) for q in qs])
    joint = joint_of("revolute", revolute.fit(points))
    assert axes_agree(joint, HINGE, AxisTolerance(1.0, 0.01))  # the fitted normal may point either way
    tilted = BodyJoint("revolute", HINGE.point, rotation_about_axis(np.array([1.0, 0, 0]), 0.3) @ HINGE.direction)
    assert not axes_agree(tilted, HINGE, AxisTolerance(10.0, 1.0))
    shifted = BodyJoint("revolute", HINGE.point + np.array([0.3, 0.0, 0.0]), HINGE.direction)
    assert not axes_agree(shifted, HINGE, AxisTolerance(10.0, 0.1)) and axes_agree(shifted, HINGE, AxisTolerance(10.0, 0.5))
    assert not axes_agree(SLIDE, HINGE, AxisTolerance(90.0, 10.0))
    with pytest.raises(ValueError, match="model_name"):
        joint_of("static", None)


def _door_tracks(rng, n, sigma, rigid=True):
    qs = np.linspace(0.0, 1.3, n)
    a = np.array([member_position(HINGE, [1.1, 5.0, 1.2], 0.0, q) for q in qs])
    if rigid:
        b = np.array([member_position(HINGE, [1.0, 5.0, 0.4], 0.0, q) for q in qs])
    else:  # a static point next to the door
        b = np.tile([1.3, 4.9, 0.4], (n, 1))
    cov = np.broadcast_to(sigma ** 2 * np.eye(3), (n, 3, 3))
    return a + sigma * rng.standard_normal((n, 3)), b + sigma * rng.standard_normal((n, 3)), cov


def test_rigidity_test_is_calibrated_and_rejects_a_static_point():
    rng = np.random.default_rng(0)
    p_values = []
    for _ in range(400):
        a, b, cov = _door_tracks(rng, 25, 0.04)
        test = rigidity_test(a, b, cov, cov)
        p_values.append(test.p_value)
    assert test.dof == 24 and test.spread_m > 0.5
    # Uniform p-values under rigidity: 1% below 0.01 (400 draws: SE 0.5%), a median near 0.5.
    assert np.mean(np.array(p_values) < 0.01) < 0.035 and abs(np.median(p_values) - 0.5) < 0.1
    a, b, cov = _door_tracks(rng, 25, 0.04, rigid=False)
    test = rigidity_test(a, b, cov, cov)
    assert test.p_value < 1e-6 and not test.consistent(0.01, 0.1)
    assert test.statistic == pytest.approx(chi2.isf(test.p_value, test.dof), rel=1e-6)
    with pytest.raises(ValueError, match="points_a, points_b"):
        rigidity_test(a[:3], b[:4], cov[:3], cov[:4])


def test_the_tests_chi2_tail_is_scipy_stats_one():
    from scipy.stats import chi2

    from stslam.slam.bodies.joint import _chi2_sf
    for dof in (1, 2, 7, 40):
        for stat in (-1.0, 0.0, 1e-300, 0.3, 2.0 * dof, 1e3, np.inf):
            assert _chi2_sf(stat, dof) == float(chi2.sf(stat, dof))
    assert np.isnan(_chi2_sf(np.nan, 3))
