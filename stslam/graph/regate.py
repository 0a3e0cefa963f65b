"""The final re-test of the observations the causal gates kept out (SPEC 6.5, 14).

A χ² gate decides on the estimate of the moment: when the robot estimate has
drifted, observations of static points fail it that are consistent with where
the robot really was, and the EKF loses them for good. The smoother still has
every pose. After the last frame each observation that was offered to a
landmark chain but did not become a factor is tested again, with the same
χ² bound (3 dof, ``Isam2Settings.regate_probability``), against the smoothed
estimate: its NIS on iSAM2's joint marginal of the pose of its frame and the
variable it would have been read on (:func:`stslam.graph.observing.passes`).
Those that pass become factors, and the test is repeated on the new estimate
until none passes (at most ``MAX_ROUNDS`` times), since each round's factors
move the estimate the next round tests against. With ``robust``
(``Isam2Settings.regate_robust``) those that still fail enter with a Huber
kernel whose threshold is the same bound on the whitened error, ‖e‖ = √χ²:
one in a hundred noise draws of a static point lies past the bound and still
counts nearly fully (a robust kernel where the causal estimate needs a gate:
SPEC 14). Only chains whose failures are as few as a static point's get it:
of n observations a static point fails a gate of probability p about
Binomial(n, 1 − p) times, and a chain with more failures than that law's
p-quantile is a point that moved (the gated baseline has no policy to say so),
whose failures, many σ off, would each still pull with weight k/‖e‖.

Most tests need no marginal: a marginal recorded at the observation's causal
gate (the frame's prior, before its own factors and every later one) or asked
in an earlier round bounds the one a round would ask for, so the bound of
:func:`~stslam.graph.observing.passes` computed on it (times ``STALE_FACTOR``)
rejects a failure that is far off without asking.

A chain whose static point was replaced by an articulated block is left out:
the policy found that landmark moving, so the observations it kept out are a
moving point's, not a drifted robot's.
"""

from __future__ import annotations

from scipy.stats import binom, chi2

import numpy as np

from stslam.graph.covariance import block_marginals, covariance_of
from stslam.graph.observing import add_observation, passes
from stslam.graph.reread import latest, reread

MAX_ROUNDS = 5
# A marginal at a causal gate or of an earlier round, times this, bounds the same variable's marginal in a later
# round: adding factors only shrinks a marginal of the linearised system (a withdrawal forgets its factors' keys'
# marginals: reread.withdraw), and relinearisation moves it by far less than this (the factors' Jacobians
# change by heading steps of about Isam2Settings.relinearize_threshold).
# Kitchen seed 0, gated smoother: the same passes in every round as without the bounds, 860 solves instead of 4,055.
STALE_FACTOR = 2.0


def candidates(state) -> list:
    """(chain, frame) of every offered observation without a factor, on chains not found moving, whose
    variable the smoother still holds (a body member's observation kept out is recorded on its founder's
    variable of that frame, which a re-read of the founder's chain may have left without factors)."""
    return [(chain, t) for chain in state._all_chains if not chain.moving
            for t in sorted(chain.offered) if t not in chain.used and t in chain.at
            and state._solver.holds(chain.at[t][0])]


def regate(state, probability: float, robust: bool = False) -> int:
    """Re-test the gated-out observations against the smoothed estimate (module docstring); how many passed."""
    bound = float(chi2.ppf(probability, 3))
    passed_total, earlier = 0, {}

    def upper(key):
        # A marginal of the smoothed system is at most the same variable's at its causal gate, and at most an
        # earlier round's (the system then held fewer factors), up to relinearisation: STALE_FACTOR's margin.
        known = earlier.get(key, state._gate_marginals.get(key))
        return None if known is None else STALE_FACTOR * known

    for _ in range(MAX_ROUNDS):
        state._flush()
        tests = candidates(state)  # (iSAM2's own queries cost most in a round after new factors: factor at once)
        covariance = covariance_of(state._solver, len(tests))  # at most one factorisation a round (covariance module)
        passed = [(chain, t) for chain, t in tests
                  if passes(state, t, *chain.at[t], *chain.offered[t], bound, covariance, upper)]
        for chain, t in passed:
            add_observation(state, t, *chain.at[t], *chain.offered[t], chain)
        passed_total += len(passed)
        if not passed:
            break
        earlier.update(covariance.known())
    if robust:
        left: dict = {}
        for chain, t in candidates(state):
            left.setdefault(id(chain), (chain, []))[1].append(t)
        for chain, frames in left.values():
            # A static point's n observations fail a gate of probability p about Binomial(n, 1 − p) times;
            # more than its p-quantile of failures is a point that moved, whose failures stay out.
            if len(frames) <= binom.ppf(probability, len(chain.offered), 1.0 - probability):
                for t in frames:
                    add_observation(state, t, *chain.at[t], *chain.offered[t], chain, huber_k=bound**0.5)
    state._flush()
    return passed_total


def finish(state) -> tuple[np.ndarray, np.ndarray]:
    """The end of a run of :class:`~stslam.graph.state.GraphState`: the re-reads still pending, the final
    re-test (``regate_probability``, full smoother only), the structure priors loosened (``structure_sigma_final``,
    full smoother only), then at most ``final_iterations`` relinearisations;
    returns the smoothed trajectory (k+1, 3) and its marginal covariances (k+1, 3, 3)."""
    from stslam.graph.prior import HeldJoints
    from stslam.graph.state import pose_key

    for i, pending in list(state._pending.items()):  # never updated again: noises as stored
        if pending.frame < state.k:
            reread(state, latest(state, i, state._pending.pop(i)), state._chains[i])
    state._flush()
    settings = state.settings
    if settings.regate_probability is not None and not state._solver.windowed:
        regate(state, settings.regate_probability, settings.regate_robust)
    if settings.structure_sigma_final is not None and not state._solver.windowed:
        state._structures.loosen(state, settings.structure_sigma_final)  # (after the re-test: its bounds assume
        state._flush()  # that marginals only shrink, which a looser prior undoes)
    for _ in range(settings.final_iterations):
        if not state._solver.relinearize():
            break
    state._guess, state._joints = {}, HeldJoints()
    poses = np.array([state.value(pose_key(k)) for k in range(state.k + 1)])
    covs = np.array(block_marginals(state._solver, [pose_key(k) for k in range(state.k + 1)]))
    return poses, covs
