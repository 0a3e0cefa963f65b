"""Re-reading a landmark's past observations under the model it was converted to (SPEC 6.3, 14).

Before A-SLAM decides, a landmark is a gated static point: observations of a
moving one mostly fail the gate, and the few that pass are read as a point
that does not move. The EKF cannot revisit them; a smoother can. At a
conversion from a static point to an articulated block, the static chain's
factors are taken out of the graph and every observation offered to that
landmark since its chain began (accepted or gated out) is put back as an
observation of the articulated block: one motion-state variable per observed
frame, tied by the block's transition composed over each gap (SPEC 3), and the
last one tied the same way to the block's variable at the conversion frame.

Each re-read observation gets the noise R · s, s the structure scale the policy
gives the landmark's first articulated update after the conversion (the ratio
of that update's R to the conversion observation's raw R): the structure error
that the scale stands for is the same for past and future observations. q of
each frame is the block's inverse kinematics of the point seen from the
smoothed pose, unwrapped over time for a revolute block and shifted by whole
turns onto the conversion variable's φ.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from stslam.graph import factors
from stslam.robot.sensor import point_from_observation

# Std of the priors that keep re-read chains determined where nothing else does: the
# static chain's orphaned variables, the first re-read frame's rates (units of the variable).
LOOSE_SIGMA = 10.0


@dataclass
class Chain:
    """One landmark chain: observations offered per frame, its variable keys and its iSAM2 factor indices."""

    block: object
    offered: dict = field(default_factory=dict)  # frame -> (z (3,), R (3, 3)), first offer per frame
    keys: list = field(default_factory=list)
    factor_indices: list = field(default_factory=list)


@dataclass
class Pending:
    """A conversion whose re-read waits for the structure scale (the landmark's next articulated update)."""

    old: Chain
    block: object
    frame: int
    target: int  # key of the block's variable at the conversion frame
    R_raw: np.ndarray  # the conversion observation's noise


def is_static_to_articulated(old_block, new_block) -> bool:
    """A conversion whose past can be re-read: a static point (no motion state) to a block with a model."""
    return not hasattr(old_block, "model") and hasattr(new_block, "model") and hasattr(new_block, "structure")


def scale_of(R_used, R_raw) -> float:
    """s = tr(R_used) / tr(R_raw): the structure scale in the landmark's first articulated update."""
    return float(np.trace(np.asarray(R_used, dtype=float)) / np.trace(np.asarray(R_raw, dtype=float)))


def reread(state, pending: Pending, scale: float, chain_id) -> None:
    """Replace ``pending.old``'s factors by articulated observations of ``pending.block`` on new variables.

    ``state`` is the :class:`~stslam.graph.state.GraphState`; its factors are flushed first so
    the old chain's factor indices are all known. New variables and factors belong to ``chain_id``.
    """
    from stslam.graph.state import pose_key

    state._flush()
    old, block = pending.old, pending.block
    frames = sorted(t for t in old.offered if t < pending.frame)
    if not frames:
        return
    floor = state.settings.floor_sigma
    state._removals.extend(old.factor_indices)
    for key in old.keys:  # orphaned, each keeps a loose prior so the system stays determined
        state._add(factors.loose_prior_factor(key, state.value(key), LOOSE_SIGMA))
    points = [point_from_observation(state.value(pose_key(t)), old.offered[t][0])[0] for t in frames]
    target_x = state.value(pending.target)
    points.append(block.position(target_x)[0])
    q = block.model.motion_variable(block.structure, np.array(points))
    if block.model.name == "revolute":  # whole turns onto the conversion variable's φ
        q = q + 2 * np.pi * np.round((target_x[: block.dof] - q[-1]) / (2 * np.pi))
    keys = []
    for t, q_t in zip(frames, q[:-1], strict=True):
        x_t = np.zeros(block.size)
        x_t[: block.dof] = q_t
        key = state._landmark_key()
        state._new(key, x_t, chain_id)
        keys.append(key)
        z, R = old.offered[t]
        state._add(factors.observation_factor(pose_key(t), key, block, z, scale * R, 0.0), chain_id)
    rates = np.arange(block.dof, block.size)
    state._add(factors.selected_prior_factor(keys[0], np.zeros(block.size), rates,
                                             LOOSE_SIGMA**2 * np.eye(rates.size), 0.0), chain_id)
    for (t0, k0), (t1, k1) in zip(zip(frames, keys), [*zip(frames[1:], keys[1:]), (pending.frame, pending.target)]):
        F, Q = state.transition_between(block, t0, t1)
        state._add(factors.linear_factor(k0, k1, F, np.zeros(block.size), Q, floor), chain_id)
