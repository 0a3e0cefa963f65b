"""Observation factors of :class:`~stslam.graph.state.GraphState`, with the structure fixed or a variable (SPEC 14).

With ``Isam2Settings.structure == "variable"`` every articulated structure C
the policy hands the state (at a conversion or a refit) gets one variable δ,
its correction (:mod:`stslam.graph.structure`), made at its first use with a
loose prior at zero (the fit) and no other: the structure is what the
observations read on it say, and nothing the selector saw is counted twice.
Its observation factors are then on (pose, motion state, δ), and the χ² gate
is the NIS on iSAM2's joint marginal of the three, so the structure's
uncertainty widens the gate as κ does for a fixed structure.

Gates and selection covariances take every observation of a batch from one
joint marginal (:func:`innovations`); :func:`local_state` is the EKF state of
the current pose and some landmarks from iSAM2's joint marginal (A-SLAM's
consensus trial).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stslam.graph import factors
from stslam.graph.covariance import SolverCovariance
from stslam.graph.prior import slices
from stslam.graph.reread import LOOSE_SIGMA
from stslam.graph.structure import SIZES
from stslam.slam.core import SlamState


@dataclass
class PriorFactor:
    """iSAM2's index of one δ's prior factor (:meth:`~stslam.graph.state.GraphState._flush` fills it as a Chain's)."""

    factor_indices: list = field(default_factory=list)


class StructureKeys:
    """The δ variable of each structure object used so far (by identity), made on first use."""

    def __init__(self, variable: bool, sigma: float = LOOSE_SIGMA):
        self.variable, self.sigma = variable, sigma
        self._keys: dict = {}  # id(structure) -> (key, structure)
        self._priors: dict = {}  # δ's key -> its PriorFactor

    def loosen(self, state, sigma: float) -> int:
        """Replace every δ's prior (std ``self.sigma`` at zero, the fit) by one of std ``sigma``; how many.

        The fit is made from observations the graph also holds (re-read on its structure), so a prior at
        the fit counts them twice: a refit makes a new δ with a new prior, and the kitchen's A-SLAM holds
        about 290 of them, each tying its structure to where the estimate put it at that fit. Online the
        prior keeps Gauss-Newton's steps in the directions few observations span from running away; after
        the last frame it is loosened (``Isam2Settings.structure_sigma_final``), and the caller's
        relinearisations carry the estimate to the new optimum. Taken out at the next update.
        """
        n = 0
        for key, prior in self._priors.items():
            if prior.factor_indices and state._solver.holds(key):
                state._removals.extend(prior.factor_indices)
                prior.factor_indices = []
                state._add(factors.loose_prior_factor(key, np.zeros(state.value(key).size), sigma), prior)
                n += 1
        return n

    def existing(self, block):
        """δ's key for ``block``'s structure if it has one already, else None (nothing is made)."""
        found = self._keys.get(id(getattr(block, "structure", None)))
        return found[0] if found is not None and found[1] is getattr(block, "structure", None) else None

    def key(self, state, block):
        """δ's key for ``block``'s structure, or None (structure fixed, or not an articulated block)."""
        structure = getattr(block, "structure", None)
        if not self.variable or structure is None or block.model.name not in SIZES:
            return None
        found = self._keys.get(id(structure))
        if found is not None and found[1] is structure:
            return found[0]
        key = state._landmark_key(SIZES[block.model.name])
        zero = np.zeros(SIZES[block.model.name])
        state._new(key, zero)
        prior = self._priors[key] = PriorFactor()  # (it stays: δ determined if orphaned)
        state._add(factors.loose_prior_factor(key, zero, self.sigma), prior, leaf=True)
        state._pred.record_prior(key, self.sigma**2 * np.eye(zero.size))  # (its marginal for the frame's gates)
        self._keys[id(structure)] = (key, structure)
        return key


def add_observation(state, frame: int, key, block, z_robot, R, chain, huber_k=None) -> None:
    """The observation factor of z at ``frame`` on the block variable ``key`` (and δ when it is a variable),
    with a Huber kernel at ``huber_k`` if given (:mod:`stslam.graph.regate`)."""
    from stslam.graph.state import pose_key

    chain.used.add(frame)
    s = state._structures.key(state, block)
    if s is None:
        state._add(factors.observation_factor(pose_key(frame), key, block, z_robot, R, 0.0, huber_k), chain)
    else:
        state._add(factors.structured_observation_factor(pose_key(frame), key, s, block, z_robot, R, 0.0, huber_k),
                   chain)


def innovations(state, landmark_ids, zs_robot, Rs) -> list:
    """(e, S) of one observation of each landmark at the current frame, all from one joint marginal.

    e = h(pose, X[, δ]) − z and S = H P Hᵀ + R (SPEC 5.3), H the observation's Jacobian on its
    keys (the pose, the landmark's variable at this frame, δ when its structure is a variable) and
    P the joint marginal of every key of the batch before the factors buffered at this frame
    (:meth:`~stslam.graph.state.GraphState.joint`): the EKF's NIS (SPEC 6.5) on the frame's prior
    marginals, one marginal for a batch where one per landmark cost an iSAM2 update each.
    """
    from stslam.graph.state import pose_key

    blocks = [state.block(i) for i in landmark_ids]
    per = [[pose_key(state.k), state._advance(i)] for i in landmark_ids]
    for keys, block in zip(per, blocks, strict=True):
        s = state._structures.key(state, block)
        if s is not None:
            keys.append(s)
    distinct = list(dict.fromkeys(k for keys in per for k in keys))
    P = state.joint(distinct)
    values = {k: state.value(k) for k in distinct}
    at = dict(zip(distinct, slices([values[k].size for k in distinct]), strict=True))
    state._gate_marginals.update((k, P[np.ix_(at[k], at[k])]) for k in distinct)
    out = []
    for keys, block, z, R in zip(per, blocks, np.asarray(zs_robot, dtype=float).reshape(-1, 3), Rs, strict=True):
        args = [values[k] for k in keys]
        if len(keys) == 3:
            e, J = factors.structured_observation_residual(*args, block, z)
        else:
            e, J = factors.observation_residual(*args, block, z)
        rows = np.concatenate([at[k] for k in keys])
        H = np.hstack(J)
        out.append((e, H @ P[np.ix_(rows, rows)] @ H.T + np.asarray(R, dtype=float)))
    return out


def joint_nis(covariance, keys, e, J, R) -> float:
    """eᵀS⁻¹e with S = H P Hᵀ + R, H = [J_k] and P the joint marginal of ``keys`` (SPEC 5.3) that ``covariance``
    (:mod:`stslam.graph.covariance`) gives."""
    H = np.hstack(J)
    S = H @ covariance.joint(keys) @ H.T + R
    return float(e @ np.linalg.solve(S, e))


def passes(state, frame: int, key, block, z_robot, R, bound: float, covariance, upper=None) -> bool:
    """Whether yᵀS⁻¹y ≤ ``bound`` for an observation z of ``frame`` read on variable ``key`` (``block``), with
    S = H P Hᵀ + R and P iSAM2's joint marginal of that frame's pose, the variable and δ when the structure
    is one (SPEC 5.3, 6.5).

    The joint marginal is costly in a large tree, so bounds decide first: R ≤ S gives
    yᵀS⁻¹y ≤ yᵀR⁻¹y, and P ≤ m blockdiag(P_ii) for m blocks (P is positive semi-definite) gives
    yᵀS⁻¹y ≥ yᵀS̄⁻¹y with S̄ = m Σ Hᵢ P_ii Hᵢᵀ + R, from the per-variable marginals; only what falls between
    asks for the joint marginal. Both come from ``covariance`` (:func:`stslam.graph.covariance.covariance_of`
    on the current estimate; a δ first read here is not in it: the solver answers). ``upper`` (key → a matrix
    ≥ that key's marginal, or None) lets S̄ reject before any marginal is asked (:mod:`stslam.graph.regate`).
    """
    from stslam.graph.state import pose_key

    s = state._structures.key(state, block)
    keys = [pose_key(frame), key] + ([] if s is None else [s])
    if s is not None and state._values.exists(s):  # δ of a structure first read here: iSAM2 takes it first
        state._flush()
        covariance = SolverCovariance(state._solver)
    values = [state.value(k) for k in keys]
    if s is None:
        e, J = factors.observation_residual(*values, block, z_robot)
    else:
        e, J = factors.structured_observation_residual(*values, block, z_robot)
    R = np.asarray(R, dtype=float)
    if e @ np.linalg.solve(R, e) <= bound:
        return True
    bounds = None if upper is None else [upper(k) for k in keys]
    if bounds is not None and all(P_i is not None for P_i in bounds) and _nis_below(e, J, bounds, R) > bound:
        return False
    marginals = covariance.marginals(keys)
    if _nis_below(e, J, marginals, R) > bound:
        return False
    return joint_nis(covariance, keys, e, J, R) <= bound


def _nis_below(e, J, marginals, R) -> float:
    """yᵀS̄⁻¹y ≤ yᵀS⁻¹y, S̄ = m Σ Hᵢ P_ii Hᵢᵀ + R from m per-variable marginals, or from upper bounds of them
    (:func:`passes`)."""
    S_upper = len(J) * sum(J_i @ P_i @ J_i.T for J_i, P_i in zip(J, marginals, strict=True)) + R
    return float(e @ np.linalg.solve(S_upper, e))


def local_state(state, landmark_ids) -> SlamState:
    """An EKF state of the current pose and these landmarks' blocks from iSAM2's joint marginal.

    For a linear-Gaussian model the joint marginal is exactly what the EKF
    would hold; NIS and trial updates on it are the EKF's own code.
    """
    from stslam.graph.state import pose_key

    keys = [state._advance(i) for i in landmark_ids]
    state._flush()
    all_keys = [pose_key(state.k), *keys]
    # Landmarks may share a variable (a body's members read their founder's): the joint marginal
    # of the distinct keys, each landmark's block a copy of its variable's rows.
    distinct = list(dict.fromkeys(all_keys))
    values = {key: state.value(key) for key in distinct}
    at = dict(zip(distinct, slices([values[key].size for key in distinct]), strict=True))
    rows = np.concatenate([at[key] for key in all_keys])
    P = state._solver.joint(distinct)
    P = P if len(distinct) == len(all_keys) else P[np.ix_(rows, rows)]
    x = np.concatenate([values[key] for key in all_keys])
    blocks = [(i, state.block(i)) for i in landmark_ids]
    return SlamState.from_blocks(x, P, blocks, state.motion_order)
