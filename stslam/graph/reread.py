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

With ``Isam2Settings.reread_restarts`` the static past re-read at a conversion
includes the static chains that A-SLAM's restarts ended before the current one
(a static point restarts when its gate rejects it ``restart_after`` times in a
row: it moved, and the observations its chain took while it started to move
are a moving point's read as a fixed one, which a smoother spreads over every
pose; :class:`Chain` ``earlier``).

At a refit of an articulated block the same is done with the landmark's own
chain: every observation it has (the re-read static past included) is read
again on the refitted structure, so the final graph reads all of them with the
latest structure rather than each with the one current at its frame.

Re-read observations get the noise the policy gives the landmark's next
update (its R times the structure scale, :mod:`stslam.slam.landmark_policy`):
each stored R is rescaled by that update's R over the R it was read with, as
the structure error the scale stands for is the same for past and future
observations. q of
each frame is the block's inverse kinematics of the point seen from the smoothed pose; for a
revolute block unwrapped over time and shifted by whole turns onto the conversion variable's φ,
then, gap by gap back from it, onto the φ the block's transition runs back to (x_next = F x_t):
between observations far apart it may turn more than half a turn, which unwrapping cannot see.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from stslam.graph import factors
from stslam.robot.sensor import point_from_observation

# Std of the priors that keep variables determined where nothing else does: the first re-read
# frame's rates, a structure correction (units of the variable).
LOOSE_SIGMA = 10.0


@dataclass
class Chain:
    """One landmark chain: observations offered per frame, its variable keys and its iSAM2 factor indices.

    ``at`` and ``used`` serve the final re-test of gated-out observations (:mod:`stslam.graph.regate`):
    the variable and block an observation of each frame would be read on, and the frames whose
    observation is a factor. ``moving``: the chain was a static point replaced by an articulated block.
    ``earlier``: the static chains of the same landmark that restarts ended just before this one began,
    oldest first (``Isam2Settings.reread_restarts``: a conversion re-reads them with it).
    """

    block: object
    offered: dict = field(default_factory=dict)  # frame -> (z (3,), R (3, 3)), first offer per frame
    keys: list = field(default_factory=list)
    factor_indices: list = field(default_factory=list)
    at: dict = field(default_factory=dict)  # frame -> (key, block)
    used: set = field(default_factory=set)  # frames with an observation factor
    moving: bool = False
    next_reread: int = 0  # first frame at which a refit's re-read may run (Isam2Settings.reread_refit_frames)
    earlier: list = field(default_factory=list)


@dataclass
class Pending:
    """A conversion whose re-read waits for the structure scale (the landmark's next articulated update)."""

    old: Chain
    block: object
    frame: int
    target: int  # key of the block's variable at the conversion frame
    R_raw: np.ndarray | None  # the conversion observation's noise; None: a refit (all past R replaced)


def is_static_to_articulated(old_block, new_block) -> bool:
    """A conversion whose past can be re-read: a static point (no motion state) to a block with a model."""
    return not hasattr(old_block, "model") and hasattr(new_block, "model") and hasattr(new_block, "structure")


def rereadable(block) -> bool:
    """Whether a static chain's past can be re-read: a point held by one variable (no random walk). A walking
    point's chain has a variable per frame tied by its walk, which a re-read does not take apart."""
    return not getattr(block, "sigma_walk", 0.0)


def is_restart(old_block, new_block) -> bool:
    """A static point put back as a static point at the same frame: A-SLAM's restart of a point that failed
    its gate ``restart_after`` times in a row (it moved, or was lost)."""
    return not hasattr(old_block, "model") and not hasattr(new_block, "model")


def _trace(R) -> float:
    return float(np.trace(np.asarray(R, dtype=float)))


def reread(state, pending: Pending, chain: Chain, R_now=None) -> None:
    """Replace ``pending.old``'s factors by observations of ``pending.block`` on new variables of ``chain``.

    ``state`` is the :class:`~stslam.graph.state.GraphState`; the old chain's factors not yet in iSAM2
    leave its buffer (:func:`unbuffer`), those in it are removed at the next update, so a re-read goes
    to iSAM2 together with the frame's other factors, in its one update; ``R_now`` the noise the
    landmark's current update uses (None: keep the stored noises). Each stored R is multiplied by
    tr(R_now)/tr(R_ref), R_ref the conversion observation's raw R, or for a refit the chain's latest
    stored R (the scale the chain's observations have been read with so far); the rescaled noises are
    stored in ``chain`` for the next refit.
    """
    from stslam.graph.observing import add_observation
    from stslam.graph.state import pose_key

    old, block, frame = pending.old, pending.block, pending.frame
    refit = pending.R_raw is None
    chains = [old] if refit else [*old.earlier, old]  # a conversion: the restarted static chains too
    seen: dict = {}
    for c in chains:  # a restart's frame was offered to both chains: the later one's
        seen.update(c.offered)
    frames = sorted(t for t in seen if t < frame or (refit and t == frame))
    past = [t for t in frames if t < frame]
    if not past:
        return
    reference = pending.R_raw if not refit else seen[frames[-1]][1]
    ratio = 1.0 if R_now is None else _trace(R_now) / _trace(reference)
    offered = {t: (seen[t][0], ratio * seen[t][1]) for t in frames}
    for c in chains:
        unbuffer(state, c, pending.target)
        state._removals.extend(c.factor_indices)
        # The chain's other variables are left without factors: iSAM2 drops such variables at the update
        # (a variable kept with a prior of its own would stay in every later update's bookkeeping).
        c.factor_indices, c.keys = [], [k for k in c.keys if k == pending.target]
        c.used, c.at = set(), {t: v for t, v in c.at.items() if v[0] == pending.target}
    for c in old.earlier:
        c.moving = True  # what it kept out was a moving point's (regate)
    old.earlier = []
    points = [point_from_observation(state.value(pose_key(t)), offered[t][0])[0] for t in past]
    target_x = state.value(pending.target)
    points.append(block.position(target_x)[0])
    q = block.model.motion_variable(block.structure, np.array(points))
    if block.model.name == "revolute":  # whole turns onto the conversion variable's φ
        q = q + 2 * np.pi * np.round((target_x[: block.dof] - q[-1]) / (2 * np.pi))
        x_next = target_x  # then each gap's turns from the block's transition over it, run back (x_next = F x_t)
        for j in range(len(past) - 1, -1, -1):
            F, _ = state.transition_between(block, past[j], ([*past[1:], frame])[j])
            x_next = np.linalg.lstsq(F, x_next, rcond=None)[0]
            q[j] = q[j] + 2 * np.pi * np.round((x_next[: block.dof] - q[j]) / (2 * np.pi))
            x_next[: block.dof] = q[j]
    keys = []
    for t, q_t in zip(past, q[:-1], strict=True):
        x_t = np.zeros(block.size)
        x_t[: block.dof] = q_t
        key = state._landmark_key(block)
        state._new(key, x_t, chain)
        keys.append(key)
        chain.at[t] = (key, block)
        add_observation(state, t, key, block, *offered[t], chain)
    if frame in offered:  # a refit: the frame's own observation, on the refit's variable
        add_observation(state, frame, pending.target, block, *offered[frame], chain)
    rates = np.arange(block.dof, block.size)
    if rates.size:  # an order-0 block has no rates (and gtsam cannot take a noise model of size 0)
        state._add(factors.selected_prior_factor(keys[0], np.zeros(block.size), rates,
                                                 LOOSE_SIGMA**2 * np.eye(rates.size), 0.0), chain)
    for (t0, k0), (t1, k1) in zip(zip(past, keys), [*zip(past[1:], keys[1:]), (frame, pending.target)]):
        F, Q = state.transition_between(block, t0, t1)
        state._add(factors.linear_factor(k0, k1, F, np.zeros(block.size), Q, state.settings.floor_sigma), chain)
    chain.offered.update(offered)


def unbuffer(state, chain: Chain, keep) -> None:
    """Take ``chain``'s buffered factors out of ``state``'s buffer, and the buffered variables no other buffered
    factor reads (but ``keep``): what a re-read removes from iSAM2 it need not hand to iSAM2 first (the
    flush that would give those factors their indices was one more iSAM2 update per re-read)."""
    import gtsam

    if not any(owner is chain for owner in state._owners):
        return
    graph, owners, used = gtsam.NonlinearFactorGraph(), [], set()
    for n, owner in enumerate(state._owners):
        if owner is not chain:
            graph.add(state._graph.at(n))
            owners.append(owner)
            used.update(state._graph.at(n).keys())
    for key in list(state._values.keys()):
        if key not in used and key != keep and key in chain.keys:
            state._values.erase(key)
            state._guess.pop(key, None)
            state._observed.discard(key)
    state._graph, state._owners = graph, owners


def withdraw(state, landmark_id, since: int) -> int:
    """Remove a static point's observation factors of frames ``since`` and later (SPEC 18); how many.

    A-SLAM's onset test flags a point that has begun to move a few frames after its motion began
    (:func:`stslam.slam.onsets.onsets`); the observations it took meanwhile are a moving point's read as a
    fixed one's, which a smoother spreads over every pose (the EKF's counterpart: :mod:`stslam.slam.replay`).
    They stay offered, for a re-read at a conversion and the final re-test (:mod:`stslam.graph.regate`). The
    chain's first observation stays, so that its variable keeps a factor. Only a static point held by one
    variable (:func:`rereadable`), and only on a solver that can list a factor's keys.
    """
    import gtsam

    chain = state._chains.get(landmark_id)
    keys_of = getattr(state._solver, "factor_keys", None)
    if chain is None or chain.moving or hasattr(chain.block, "model") or not rereadable(chain.block) or keys_of is None:
        return 0
    state._flush()  # every factor of the chain numbered
    observed = []  # (frame, index) of the chain's observation factors: those on a pose
    for index in chain.factor_indices:
        frames = [gtsam.Symbol(key).index() for key in keys_of(index) if gtsam.Symbol(key).chr() == ord("x")]
        if frames:
            observed.append((frames[0], index))
    gone = [(t, index) for t, index in sorted(observed)[1:] if t >= since]
    for t, index in gone:
        chain.factor_indices.remove(index)
        chain.used.discard(t)
        state._removals.append(index)
        for key in keys_of(index):  # less information: their marginals at a gate no longer bound them (regate)
            state._gate_marginals.pop(key, None)
    return len(gone)


def offer(state, landmark_ids, zs_robot, R) -> None:
    """Remember each observation offered to ``state`` at this frame (the first per landmark), for a later re-read."""
    zs = np.asarray(zs_robot, dtype=float).reshape(len(landmark_ids), 3)
    R = np.asarray(R, dtype=float)
    for j, i in enumerate(landmark_ids):
        state._chains[i].offered.setdefault(state.k, (zs[j].copy(), (R[j] if R.ndim == 3 else R).copy()))


def latest(state, landmark_id, pending: Pending) -> Pending:
    """A refit's re-read ending at the landmark's latest variable, where the refit's own one has been carried
    on since (a waiting re-read: the chain's factors after the refit are re-read too); a conversion's as it is."""
    head = state._heads.get(landmark_id)
    if pending.R_raw is not None or head is None or head[2] is not pending.block:
        return pending
    return replace(pending, target=head[0], frame=head[1])


def reread_pending(state, landmark_ids, Rs) -> None:
    """Re-read the static past of converted landmarks at their first articulated update, and the past of
    refitted ones at their first update once ``reread_refit_frames`` have passed since their last (module
    docstring; :class:`~stslam.graph.settings.Isam2Settings`)."""
    for j, i in enumerate(landmark_ids):
        pending = state._pending.get(i)
        if pending is None or pending.frame >= state.k:
            continue
        chain = state._chains[i]
        refit = pending.R_raw is None
        if refit and state.k < chain.next_reread:
            continue  # it waits (a later refit supersedes it; the last is done at the end: regate.finish)
        del state._pending[i]
        reread(state, latest(state, i, pending), chain, Rs[j])
        if refit:
            chain.next_reread = state.k + state.settings.reread_refit_frames
