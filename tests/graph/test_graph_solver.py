"""The full smoother's fallback from Cholesky to QR where Cholesky finds the system indeterminate (SPEC 14)."""

from __future__ import annotations

import numpy as np
import pytest

gtsam = pytest.importorskip("gtsam")

from stslam.graph.solver import FullSolver, Isam2Settings


def _prior(key, value, sigma):
    return gtsam.PriorFactorVector(key, np.asarray(value, dtype=float), gtsam.noiseModel.Isotropic.Sigma(2, sigma))


def _between(key_from, key_to, step, sigma):
    return gtsam.BetweenFactorVector(key_from, key_to, np.asarray(step, dtype=float),
                                     gtsam.noiseModel.Isotropic.Sigma(2, sigma))


A, B, C, D = (gtsam.symbol(letter, 0) for letter in "abcd")


def _steps():
    """Three updates as (factors, values, removals given as (update, position) of an earlier factor). The
    second ties b to a with σ = 1e-9 beside a's prior of σ = 1: the Jacobian's conditioning (1e9) is fine for
    QR, but its square, the Hessian Cholesky factors, rounds b's pivot to zero (1 + 1e18 == 1e18)."""
    return [
        ([_prior(A, [0.0, 0.0], 1.0), _between(A, C, [1.0, 0.0], 0.5)], {A: [0.1, 0.0], C: [1.2, 0.1]}, []),
        ([_between(A, B, [0.0, 1.0], 1e-9), _prior(C, [1.0, 0.2], 0.3)], {B: [0.0, 0.9]}, [(0, 1)]),
        ([_between(C, D, [0.0, 1.0], 0.2), _between(B, D, [1.0, 0.0], 0.4)], {D: [1.1, 1.1]}, [(1, 1)]),
    ]


def _run(settings):
    """Feed :func:`_steps` to a FullSolver; per update the returned indices, and after it the estimate and
    marginal of every variable held."""
    solver, indices, seen = FullSolver(settings), [], []
    for factors, values, removals in _steps():
        graph, initial = gtsam.NonlinearFactorGraph(), gtsam.Values()
        for factor in factors:
            graph.add(factor)
        for key, value in values.items():
            initial.insert(key, np.asarray(value, dtype=float))
        indices.append(solver.update(graph, initial, [indices[u][p] for u, p in removals], 0.0))
        seen.append({key: (solver.estimate(key), solver.marginal(key)) for key in (A, B, C, D) if solver.holds(key)})
    return solver, indices, seen


def test_cholesky_raises_on_the_stiff_graph_without_the_fallback():
    """Plain iSAM2 under Cholesky cannot take :func:`_steps`' second update (what the fallback is for)."""
    isam = gtsam.ISAM2(gtsam.ISAM2Params())
    for step, (factors, initial, removals) in enumerate(_steps()[:2]):
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        for factor in factors:
            graph.add(factor)
        for key, value in initial.items():
            values.insert(key, np.asarray(value, dtype=float))
        if step == 0:
            isam.update(graph, values)
        else:
            with pytest.raises(RuntimeError, match="Indeterminate linear system"):
                isam.update(graph, values, [1])


def test_cholesky_falls_back_to_qr_and_keeps_the_run():
    qr, qr_indices, qr_seen = _run(Isam2Settings(factorization="qr"))
    chol, chol_indices, chol_seen = _run(Isam2Settings(factorization="cholesky"))
    assert qr.fallbacks == 0 and chol.fallbacks == 1  # once, at the second update; QR from then on
    assert chol_indices == qr_indices == [[0, 1], [2, 3], [4, 5]]  # the solver's own indices across the rebuild
    for qr_step, chol_step in zip(qr_seen, chol_seen, strict=True):
        assert qr_step.keys() == chol_step.keys()
        for key in qr_step:
            np.testing.assert_allclose(chol_step[key][0], qr_step[key][0], atol=1e-9)
            np.testing.assert_allclose(chol_step[key][1], qr_step[key][1], atol=1e-9)
    # the third update removed the second's prior on c: c now only through a and d
    assert not np.allclose(chol_seen[2][C][0], chol_seen[1][C][0], atol=1e-3)


def test_an_error_that_is_not_an_indeterminate_system_is_not_caught():
    solver = FullSolver(Isam2Settings(factorization="cholesky"))
    graph = gtsam.NonlinearFactorGraph()
    graph.add(_prior(A, [0.0, 0.0], 1.0))
    with pytest.raises(RuntimeError):  # a factor on a variable given no value
        solver.update(graph, gtsam.Values(), [], 0.0)
    assert solver.fallbacks == 0


def test_an_articulated_landmarks_q_has_its_own_relinearisation_threshold():
    """A one-dof articulated block's variable is keyed in upper case, its threshold relinearize_threshold_q on q
    (first) and relinearize_threshold on the derivatives; every other variable as before."""
    from stslam.articulation.models import PrismaticStructure, get_model
    from stslam.graph.solver import key_letter, threshold_vectors
    from stslam.slam.blocks import ArticulatedBlock, ConstantVelocityPointBlock, StaticPointBlock

    line = PrismaticStructure(np.array([2.0, 0.0, 0.5]), np.array([0.0, 1.0, 0.0]), 0.0)
    order1 = ArticulatedBlock(get_model("prismatic"), line, 1, 0.01, 0.01)  # X = [q, q̇]
    assert [key_letter(order1), key_letter(2), key_letter(StaticPointBlock())] == ["C", "c", "s"]
    assert key_letter(ConstantVelocityPointBlock(0.1, 0.1)) == "y"  # (Dyn. SLAM's: linear, as a position)
    thresholds = threshold_vectors(Isam2Settings(relinearize_threshold=0.01, relinearize_threshold_m=0.05,
                                           relinearize_threshold_q=0.3))
    np.testing.assert_array_equal(thresholds["C"], [0.3, 0.01])
    np.testing.assert_array_equal(thresholds["c"], [0.01, 0.01])
    np.testing.assert_array_equal(thresholds["y"], [0.05] * 6)
    np.testing.assert_array_equal(threshold_vectors(Isam2Settings(relinearize_threshold=0.02))["B"], [0.02])
    with pytest.raises(ValueError, match="relinearize_threshold_q"):
        Isam2Settings(relinearize_threshold_q=0.0)


@pytest.mark.parametrize("factorization", ["cholesky", "qr"])
def test_a_pair_tied_only_to_each_other_is_anchored_and_nothing_else_moves(factorization):
    """Two variables tied only to each other (kitchen tuning seed 1002: a landmark's motion states left so by
    its removed factors) are placed by no factor: under either factorization the update fails, the rebuild
    under QR fails too, and a loose prior on the variable gtsam names lets it through. The rest of the graph
    keeps the estimate it has without the pair (the pair is a component of its own)."""
    E, F = gtsam.symbol("e", 0), gtsam.symbol("f", 0)

    def update(solver, with_pair):
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        for factor in (_prior(A, [0.0, 0.0], 1.0), _between(A, C, [1.0, 0.0], 0.5)):
            graph.add(factor)
        for key, value in ((A, [0.1, 0.0]), (C, [1.2, 0.1])):
            values.insert(key, np.asarray(value, dtype=float))
        if with_pair:
            graph.add(_between(E, F, [0.5, 0.0], 0.3))
            for key, value in ((E, [2.0, 2.0]), (F, [2.4, 2.1])):
                values.insert(key, np.asarray(value, dtype=float))
        return solver.update(graph, values, [], 0.0)

    plain, anchored = FullSolver(Isam2Settings(factorization=factorization)), FullSolver(
        Isam2Settings(factorization=factorization))
    update(plain, False)
    assert update(anchored, True) == [0, 1, 2]  # the solver's own indices: the prior is not one of them
    assert anchored.fallbacks == 1 and anchored.anchors == 1
    for key in (A, C):
        np.testing.assert_allclose(anchored.estimate(key), plain.estimate(key), atol=1e-9)
    # the pair keeps its relative step (its one factor) and sits near where it was put (the loose prior)
    np.testing.assert_allclose(anchored.estimate(F) - anchored.estimate(E), [0.5, 0.0], atol=1e-6)
