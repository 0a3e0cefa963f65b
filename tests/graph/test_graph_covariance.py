"""Marginals of many smoother variables from one factorisation (stslam.graph.covariance)."""

from __future__ import annotations

import numpy as np
import pytest

gtsam = pytest.importorskip("gtsam")

import stslam.graph.covariance as covariance_module
from stslam.graph.covariance import SolverCovariance, SystemCovariance, covariance_of
from stslam.graph.solver import FullSolver, Isam2Settings


@pytest.fixture
def factor_at_once(monkeypatch):
    """The system factored at the first question (the run's default waits for BUILD_AFTER of them)."""
    monkeypatch.setattr(covariance_module, "BUILD_AFTER", 0)


def _vector_factor(kind, keys, value, sigmas):
    noise = gtsam.noiseModel.Diagonal.Sigmas(np.asarray(sigmas, dtype=float))
    value = np.asarray(value, dtype=float)
    return gtsam.PriorFactorVector(*keys, value, noise) if kind == "prior" else gtsam.BetweenFactorVector(
        *keys, value, noise)


def _chain_solver(stiff: float | None = None) -> tuple[FullSolver, list]:
    """A FullSolver over a chain of 3-vectors x0..x9 with priors and four "landmarks" l0..l3 seen from several;
    ``stiff``: one more tie of σ = stiff between x9 and l3 (H's conditioning ~ 1/stiff²)."""
    rng = np.random.default_rng(4)
    xs = [gtsam.symbol("x", k) for k in range(10)]
    ls = [gtsam.symbol("l", j) for j in range(4)]
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    graph.add(_vector_factor("prior", [xs[0]], np.zeros(3), [0.01, 0.01, 0.005]))
    for k in range(9):
        graph.add(_vector_factor("between", [xs[k], xs[k + 1]], [1.0, 0.0, 0.05], [0.05, 0.05, 0.01]))
    for j, l in enumerate(ls):
        for k in range(j, 10, 2):
            graph.add(_vector_factor("between", [xs[k], l], rng.normal(0, 1, 3), [0.1, 0.2, 0.15]))
    if stiff is not None:
        graph.add(_vector_factor("between", [xs[9], ls[3]], np.zeros(3), [stiff] * 3))
    for key in xs + ls:
        values.insert(key, rng.normal(0, 0.1, 3))
    solver = FullSolver(Isam2Settings(factorization="qr"))
    solver.update(graph, values, [], 0.0)
    return solver, xs + ls


def test_the_marginals_and_joints_are_isam2_s_own(factor_at_once):
    solver, keys = _chain_solver()
    covariance = covariance_of(solver)
    assert isinstance(covariance, SystemCovariance)
    # entries of order 1e-4..1: iSAM2's Bayes tree and one sparse LU agree to rounding
    for key, block in zip(keys, covariance.marginals(keys), strict=True):
        np.testing.assert_allclose(block, solver.marginal(key), rtol=1e-7, atol=1e-12)
    for pair in ([keys[3], keys[11]], [keys[8], keys[11]], [keys[0], keys[12], keys[13]]):
        np.testing.assert_allclose(covariance.joint(pair), solver.joint(pair), rtol=1e-7, atol=1e-12)
    assert covariance._built and not covariance._failed  # (the factored system answered)


def test_an_inaccurate_solve_hands_over_to_the_solver_s_queries(factor_at_once):
    solver, keys = _chain_solver(stiff=1e-9)  # H = AᵀA squares A's 1e9: its LU cannot be trusted
    covariance = covariance_of(solver)
    pair = [keys[9], keys[13]]
    np.testing.assert_allclose(covariance.joint(pair), solver.joint(pair), rtol=1e-7, atol=1e-15)
    assert covariance._failed  # from now on every answer is the solver's
    np.testing.assert_allclose(covariance.marginal(keys[2]), solver.marginal(keys[2]), rtol=1e-12)


def test_a_windowed_smoother_answers_itself():
    solver, _ = _chain_solver()
    solver.windowed = True  # (the flag LagSolver sets)
    assert isinstance(covariance_of(solver), SolverCovariance)


def test_a_system_too_large_to_factor_asks_the_solver(monkeypatch, factor_at_once):
    solver, keys = _chain_solver()
    monkeypatch.setattr(covariance_module, "MAX_NONZEROS", 10)  # the chain's H has ~200 nonzeros
    covariance = covariance_of(solver)
    np.testing.assert_allclose(covariance.joint([keys[1], keys[10]]), solver.joint([keys[1], keys[10]]), rtol=1e-12)
    assert covariance._built and covariance._failed


def test_a_few_questions_are_iSAM2_s_to_answer():
    solver, keys = _chain_solver()
    covariance = covariance_of(solver)
    covariance.marginals(keys)  # 14 questions: not worth linearising every factor
    assert not covariance._built


def test_marginals_cut_from_joints_of_a_few_keys_at_a_time_are_isam2_s_own(monkeypatch):
    from stslam.graph.covariance import block_marginals

    solver, keys = _chain_solver()
    monkeypatch.setattr(covariance_module, "JOINT_CHUNK", 5)  # 14 keys: joints of 5, 5 and 4
    for key, block in zip(keys, block_marginals(solver, keys), strict=True):
        np.testing.assert_allclose(block, solver.marginal(key), rtol=1e-9, atol=1e-14)  # the same Bayes tree
