"""Articulation models (SPEC 2): recovery, Jacobians, inverse kinematics, degeneracy, invariance."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from stslam.articulation.models import (MODELS, PrismaticModel, RevoluteModel, StaticModel,
                                 get_model)
from stslam.errors import ConfigError, DegenerateFitError

# A lopsided frame: a tilted plane (normal not along any axis), off-origin centre.
ROT = Rotation.from_euler("xyz", [0.7, -0.4, 1.9]).as_matrix()
V1_TRUE, V2_TRUE, N_TRUE = ROT[:, 0], ROT[:, 1], ROT[:, 2]
CENTRE_TRUE = np.array([1.5, -2.0, 0.8])
RADIUS_TRUE = 0.47


def _circle_points(angles, v1=V1_TRUE, v2=V2_TRUE, centre=CENTRE_TRUE, r=RADIUS_TRUE):
    a = np.asarray(angles)[:, None]
    return centre + r * np.cos(a) * v1 + r * np.sin(a) * v2


def _fd_jacobian(model, structure, q, h=1e-6):
    cols = []
    for i in range(model.dof):
        e = np.zeros(model.dof)
        e[i] = h
        cols.append((model.position(structure, q + e) - model.position(structure, q - e)) / (2 * h))
    return np.column_stack(cols)


# ---------------------------------------------------------------- exact recovery

@pytest.mark.parametrize("sense", [1.0, -1.0])
def test_revolute_recovers_circle_axis_and_turning_sense(sense):
    # unevenly spaced angles over 100°, turning counter-clockwise about N (sense +1)
    # or clockwise (−1); the fitted normal must be the right-handed rotation axis.
    angles = sense * np.array([0.2, 0.25, 0.5, 0.9, 1.0, 1.6, 1.95])
    structure = MODELS["revolute"].fit(_circle_points(angles))
    # noise-free: only round-off remains
    assert np.allclose(structure.centre_world, CENTRE_TRUE, atol=1e-9)
    assert structure.radius == pytest.approx(RADIUS_TRUE, abs=1e-9)
    assert np.allclose(structure.axis_direction, sense * N_TRUE, atol=1e-9)
    assert np.allclose(structure.axis_point, CENTRE_TRUE, atol=1e-9)
    assert structure.residual_m < 1e-9
    assert np.allclose(np.cross(structure.v1, structure.v2), structure.normal)
    assert np.allclose([structure.v1 @ structure.v1, structure.v2 @ structure.v2, structure.v1 @ structure.v2],
                       [1.0, 1.0, 0.0], atol=1e-12)
    phi = MODELS["revolute"].motion_variable(structure, _circle_points(angles))[:, 0]
    # φ grows over the window by the true turned angles (same spacing as the input)
    assert np.allclose(np.diff(phi), np.abs(np.diff(angles)), atol=1e-9)


def test_revolute_angles_unwrap_past_pi():
    angles = np.linspace(2.5, 2.5 + 1.8 * np.pi, 20)  # crosses ±π twice
    model = MODELS["revolute"]
    structure = model.fit(_circle_points(angles))
    phi = model.motion_variable(structure, _circle_points(angles))[:, 0]
    assert np.allclose(np.diff(phi), np.diff(angles), atol=1e-9)


@pytest.mark.parametrize("sense", [1.0, -1.0])
def test_prismatic_recovers_line_with_increasing_l(sense):
    direction = np.array([0.3, -0.8, 0.52]) / np.linalg.norm([0.3, -0.8, 0.52])
    start = np.array([4.0, 1.0, -0.5])
    l_true = sense * np.array([0.0, 0.05, 0.3, 0.32, 0.9, 1.4])
    points = start + l_true[:, None] * direction
    model = MODELS["prismatic"]
    structure = model.fit(points)
    assert np.allclose(structure.direction, sense * direction, atol=1e-12)
    assert np.allclose(structure.p0, points.mean(axis=0))
    assert structure.residual_m < 1e-12
    l_fit = model.motion_variable(structure, points)[:, 0]
    assert np.all(np.diff(l_fit) > 0)
    assert np.allclose(np.diff(l_fit), np.abs(np.diff(l_true)), atol=1e-12)


def test_static_fit_is_window_mean_and_residual_is_rms_distance():
    points = np.array([[1.0, 2.0, 3.0], [1.2, 2.0, 3.0], [1.0, 2.4, 3.0], [1.0, 2.0, 2.4]])
    structure = MODELS["static"].fit(points)
    assert np.allclose(structure.p0, [1.05, 2.1, 2.85])
    expected = np.sqrt(np.mean(np.sum((points - [1.05, 2.1, 2.85]) ** 2, axis=1)))
    assert structure.residual_m == pytest.approx(expected, rel=1e-12)
    assert StaticModel().fit(points[:1]).residual_m == 0.0


def test_shapes_of_position_and_jacobian():
    rng = np.random.default_rng(0)
    window = _circle_points(np.linspace(0.0, 2.0, 7))
    for model in (*MODELS.values(), StaticModel(perturbation="isotropic")):
        structure = model.fit(window)
        q = rng.normal(size=model.dof)
        assert model.position(structure, q).shape == (3,)
        assert model.position(structure, rng.normal(size=(5, model.dof))).shape == (5, 3)
        assert model.jacobian(structure, q).shape == (3, model.dof)
        assert model.motion_variable(structure, window).shape == (7, model.dof)
    with pytest.raises(ValueError, match=r"q must have shape \(1,\) or \(n, 1\)"):
        MODELS["prismatic"].position(MODELS["prismatic"].fit(window), np.zeros(2))


# ---------------------------------------------------------------- Jacobians

@pytest.mark.parametrize("model", [*MODELS.values(), StaticModel(perturbation="isotropic")],
                         ids=["static", "prismatic", "revolute", "static_iso"])
def test_jacobian_matches_central_differences(model):
    rng = np.random.default_rng(5)
    window = _circle_points(np.linspace(0.3, 2.4, 9)) + rng.normal(0.0, 0.01, (9, 3))
    structure = model.fit(window)
    for _ in range(5):
        q = rng.normal(size=model.dof) * 2.0
        # central differences with h = 1e-6 on an O(1) smooth function: error ~h² + ε/h ≈ 1e-10
        assert np.allclose(model.jacobian(structure, q), _fd_jacobian(model, structure, q), atol=1e-8)


@pytest.mark.parametrize("model", [*MODELS.values(), StaticModel(perturbation="isotropic")],
                         ids=["static", "prismatic", "revolute", "static_iso"])
def test_second_derivative_matches_central_differences_of_the_jacobian(model):
    rng = np.random.default_rng(6)
    window = _circle_points(np.linspace(0.3, 2.4, 9)) + rng.normal(0.0, 0.01, (9, 3))
    structure = model.fit(window)
    h = 1e-6
    for _ in range(5):
        q = rng.normal(size=model.dof) * 2.0
        second = model.second_derivative(structure, q)
        assert second.shape == (3, model.dof, model.dof)
        for i in range(model.dof):
            e = np.zeros(model.dof)
            e[i] = h
            numeric = (model.jacobian(structure, q + e) - model.jacobian(structure, q - e)) / (2 * h)
            # as for the Jacobian: error ~h² + ε/h ≈ 1e-10 on O(1) values
            np.testing.assert_allclose(second[:, :, i], numeric, atol=1e-8)
    if model.name == "revolute":  # f'' points from the point to the circle centre, length r
        f2 = model.second_derivative(structure, [0.7])[:, 0, 0]
        np.testing.assert_allclose(f2, structure.centre_world - model.position(structure, [0.7]), atol=1e-14)


# ---------------------------------------------------------------- inverse kinematics

@pytest.mark.parametrize("model", [*MODELS.values(), StaticModel(perturbation="isotropic")],
                         ids=["static", "prismatic", "revolute", "static_iso"])
def test_inverse_kinematics_round_trip(model):
    rng = np.random.default_rng(9)
    window = _circle_points(np.linspace(-0.5, 1.5, 8)) + rng.normal(0.0, 0.02, (8, 3))
    structure = model.fit(window)
    q = np.cumsum(rng.uniform(0.05, 0.3, (10, model.dof)), axis=0)  # a moving q
    on_model = model.position(structure, q)
    q_back = model.motion_variable(structure, on_model)
    assert np.allclose(model.position(structure, q_back), on_model, atol=1e-12)
    if model.name != "revolute":  # angles come back modulo 2π, the rest exactly
        assert np.allclose(q_back, q, atol=1e-12)


def test_revolute_ik_returns_angles_modulo_two_pi():
    model = MODELS["revolute"]
    structure = model.fit(_circle_points(np.linspace(0.0, 1.0, 6)))
    q = np.array([[0.1], [0.4], [0.7]]) + 2 * np.pi
    q_back = model.motion_variable(structure, model.position(structure, q))
    assert np.allclose(np.diff(q_back[:, 0]), [0.3, 0.3], atol=1e-12)
    assert np.allclose(np.cos(q_back - q), 1.0, atol=1e-12)


# ---------------------------------------------------------------- degenerate windows

@pytest.mark.parametrize("model_name, points, match", [
    ("revolute", np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]]), "at least 3 distinct points, got 2"),
    ("revolute", np.array([[1.0, 1.0, 1.0]] * 5 + [[2.0, 1.0, 1.0]] * 2), "at least 3 distinct points, got 2"),
    ("revolute", np.outer(np.arange(6.0), [0.2, -0.1, 0.7]), "collinear"),
    ("prismatic", np.array([[0.5, -1.0, 2.0]] * 7), "all points are identical"),
])
def test_degenerate_windows_raise(model_name, points, match):
    with pytest.raises(DegenerateFitError, match=match):
        MODELS[model_name].fit(points)


@pytest.mark.parametrize("bad, match", [
    (np.zeros((5, 2)), r"shape \(n, 3\)"),
    (np.zeros((0, 3)), r"shape \(n, 3\)"),
    (np.array([[0.0, 0.0, np.inf], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), "non-finite"),
])
def test_bad_arrays_raise(bad, match):
    for model in MODELS.values():
        with pytest.raises(ValueError, match=match):
            model.fit(bad)


def test_get_model():
    assert get_model("prismatic").name == "prismatic"
    assert get_model("static", perturbation="isotropic").dof == 3
    assert MODELS["static"].dof == 1
    bad = [(("hinge",), {}, r"^name: expected one of static, prismatic, revolute; got 'hinge'$"),
           (("static",), {"perturbation": "gaussian"}, r"^perturbation: expected one of paper, isotropic; got 'gaussian'$"),
           (("revolute",), {"radius": 2.0}, r"^options: unknown options of the revolute model: \['radius'\]$")]
    for args, options, match in bad:
        with pytest.raises(ValueError, match=match) as caught:
            get_model(*args, **options)
        assert not isinstance(caught.value, ConfigError)


# ---------------------------------------------------------------- rigid-motion invariance

@settings(max_examples=40, deadline=None)
@given(euler=st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3),
       shift=st.lists(st.floats(-50.0, 50.0), min_size=3, max_size=3),
       seed=st.integers(0, 2**31 - 1))
def test_fits_are_invariant_under_rigid_motion(euler, shift, seed):
    rng = np.random.default_rng(seed)
    R = Rotation.from_euler("xyz", euler).as_matrix()
    t = np.array(shift)
    angles = np.sort(rng.uniform(0.0, 2.5, 8))
    window = _circle_points(angles) + rng.normal(0.0, 0.01, (8, 3))
    moved = window @ R.T + t

    rev, rev_m = RevoluteModel().fit(window), RevoluteModel().fit(moved)
    # round-off grows with |t| ≤ 87 m: 1e-7 m is far above it and far below σ = 0.01 m
    assert np.allclose(rev_m.centre_world, R @ rev.centre_world + t, atol=1e-7)
    assert rev_m.radius == pytest.approx(rev.radius, abs=1e-7)
    assert np.allclose(rev_m.axis_direction, R @ rev.axis_direction, atol=1e-7)
    assert rev_m.residual_m == pytest.approx(rev.residual_m, abs=1e-7)
    # v1 may differ by an in-plane rotation (SVD sign), so φ agrees up to a constant
    phi, phi_m = (RevoluteModel().motion_variable(s, w)[:, 0] for s, w in ((rev, window), (rev_m, moved)))
    assert np.allclose(np.diff(phi_m), np.diff(phi), atol=1e-6)

    pri, pri_m = PrismaticModel().fit(window), PrismaticModel().fit(moved)
    assert np.allclose(pri_m.direction, R @ pri.direction, atol=1e-7)
    assert np.allclose(pri_m.p0, R @ pri.p0 + t, atol=1e-7)
    assert pri_m.residual_m == pytest.approx(pri.residual_m, abs=1e-7)

    sta, sta_m = StaticModel().fit(window), StaticModel().fit(moved)
    assert np.allclose(sta_m.p0, R @ sta.p0 + t, atol=1e-7)
    assert sta_m.residual_m == pytest.approx(sta.residual_m, abs=1e-7)


def test_fits_of_a_long_window_need_memory_linear_in_its_length():
    """A 50,000-point window (half an hour of a 30 Hz marker) is fitted without an n × n matrix.

    A full SVD's U alone would be 50,000² doubles (20 GB); the thin one is 50,000 × 3.
    The fits run in compiled kernels, whose arrays tracemalloc does not see, so the test measures the
    peak resident memory of a fresh process: its rise over the fit of a 50-point window (which compiles
    the kernels) must stay under 100 MB, a few copies of the (n, 3) window (1.2 MB each) and of its
    per-point work arrays with room to spare.
    """
    script = """
import resource, numpy as np
from stslam.articulation.evidence import principal_axes
from stslam.articulation.models import get_model
rng = np.random.default_rng(5)
def window(n):
    phi = np.linspace(0.0, 1.2, n)
    return np.c_[0.7 * np.cos(phi), 0.7 * np.sin(phi), np.ones_like(phi)] + rng.normal(scale=0.003, size=(n, 3))
get_model("revolute").fit(window(50)); principal_axes(window(50))
big = window(50_000)
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
structure = get_model("revolute").fit(big); principal_axes(big)
print((resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024, structure.radius)
"""
    import subprocess
    import sys

    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    rise, radius = map(float, done.stdout.split())
    assert rise < 100e6
    assert radius == pytest.approx(0.7, abs=0.01)  # 3 mm noise on a 0.84 m arc
