"""Articulated bodies in the factor graph: members read their founder's motion-state variables (SPEC 13, 14).

:class:`GraphBodyState` is :class:`~stslam.graph.state.GraphState` with the
member table of :class:`~stslam.slam.bodies.state.BodyMembers`, so A-SLAM's body
rules (:class:`~stslam.slam.bodies.policy.BodyLandmarkPolicy`) run on it unchanged:

* a member has no variables of its own. Its observation at frame t is a factor
  on the pose x_t and the founder's motion-state variable X_b,t, read through
  the member's own structure (and, with ``structure: variable``, that
  structure's own correction δ), so every member's observation updates the
  body's one motion state, as in the EKF (SPEC 13, 5.3);
* each member keeps a chain of its own (its offered observations and the
  variables they were read on) for the final re-test (:mod:`stslam.graph.regate`);
* a member that leaves as a static point gets a point variable m tied to the
  founder's current variable by m = p_i(X) (a linear factor with J = ∂m/∂X and
  no noise beyond the floor): the EKF's augmentation of the state by m with its
  cross-covariances.
"""

from __future__ import annotations

import numpy as np

from stslam.graph import factors
from stslam.graph.reread import Chain, is_static_to_articulated
from stslam.graph.state import GraphState
from stslam.slam.bodies.state import BodyMembers

__all__ = ["GraphBodyState"]


class GraphBodyState(BodyMembers, GraphState):
    """The iSAM2 state whose landmark ids may be members of a founder's body (module docstring)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._init_members()

    def _head(self, landmark_id) -> tuple:
        member = self._members.get(landmark_id)
        if member is None:
            return super()._head(landmark_id)
        key, frame, _ = self._heads[member[0]]
        return key, frame, member[1]

    def _advance(self, landmark_id) -> int:
        """The founder's variable at the current frame for a member (recorded in the member's chain)."""
        member = self._members.get(landmark_id)
        if member is None:
            return super()._advance(landmark_id)
        key = super()._advance(member[0])
        self._chains[landmark_id].at[self.k] = (key, member[1])
        return key

    def block_q(self, founder_id) -> float:
        """q of the founder's motion state at the current frame (its latest variable carried over the gap)."""
        key, frame, block = self._heads[founder_id]
        self._sync(key, marginal=False)
        F, _ = self.transition_between(block, frame, self.k)
        return float((F @ self.value(key))[0])

    def add_member(self, landmark_id, founder_id, block, offset_cov=None) -> None:
        super().add_member(landmark_id, founder_id, block)  # (the offset is held exact here: no offset_cov)
        chain = self._chains[landmark_id] = Chain(block)
        self._all_chains.append(chain)
        frame, old = self._retired.pop(landmark_id, (None, None))
        if frame == self.k and is_static_to_articulated(old.block, block):
            old.moving = True  # it joined a moving body: what its static chain kept out was motion (regate)

    def set_member_block(self, landmark_id, block) -> None:
        super().set_member_block(landmark_id, block)
        self._chains[landmark_id].block = block

    def remove_member(self, landmark_id) -> None:
        super().remove_member(landmark_id)
        self._retired[landmark_id] = (self.k, self._chains.pop(landmark_id))

    def detach_member(self, landmark_id, block, at=None) -> None:
        """Give a member its own ``block`` (a static point) at m = p_i(X) (or ``at`` (3,)): a new variable
        tied to X (module docstring)."""
        key = self._advance(landmark_id)
        self._sync(key, marginal=False)
        x_body = self.value(key)
        m, dm_dx = self.block(landmark_id).position(x_body)
        m, dm_dx = np.asarray(m if at is None else at, dtype=float), np.atleast_2d(np.asarray(dm_dx, dtype=float))
        BodyMembers.remove_member(self, landmark_id)  # its chain ends here, not retired: no conversion follows
        self._chains.pop(landmark_id)
        new = self._landmark_key(block)
        chain = self._chains[landmark_id] = Chain(block)
        self._all_chains.append(chain)
        self._new(new, m, chain)
        chain.at[self.k] = (new, block)
        self._add(factors.linear_factor(key, new, dm_dx, m - dm_dx @ x_body, np.zeros((m.size, m.size)),
                                        self.settings.floor_sigma), chain, leaf=True)
        self._pred.record(new, key, dm_dx, np.zeros((m.size, m.size)), self._values.exists(key))
        self._heads[landmark_id] = (new, self.k, block)
