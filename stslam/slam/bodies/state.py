"""The state side of articulated bodies (SPEC 13): members that read their founder's motion state.

A member has no block of its own, only an
:class:`~stslam.slam.blocks.ArticulatedBlock` on its own structure in the body's
q, which reads the founder's motion state (:mod:`stslam.slam.bodies.grouping` holds the
grouping rules). :class:`BodyMembers` is the member table any estimator's state
can mix in; :class:`BodySlamState` is the EKF state with it, where a member's
slice of x and P is its founder's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from stslam.kalman import ekf
from stslam.slam.blocks import ArticulatedBlock, OffsetErrorBlock
from stslam.slam.core import SlamState
from stslam.slam.journal import journaled

__all__ = ["BodyMembers", "BodySlamState", "OffsetKey"]


@dataclass(frozen=True)
class OffsetKey:
    """The state's key of a member's offset error ε (:class:`~stslam.slam.blocks.OffsetErrorBlock`)."""

    member: object


class BodyMembers:
    """The member table of a state holding bodies (mixed into an estimator's state before it).

    Each member id maps to (founder id, :class:`~stslam.slam.blocks.ArticulatedBlock` on the
    member's structure); the founder is an ordinary landmark of the state. The estimator adds
    how a member's observation reads the founder's motion state and how a member leaves
    (``detach_member``).
    """

    def _init_members(self) -> None:
        self._members: dict = {}  # member id -> (founder id, ArticulatedBlock on the member's structure)

    def __contains__(self, landmark_id) -> bool:
        return landmark_id in self._members or super().__contains__(landmark_id)

    @property
    def landmark_ids(self) -> list:
        return [*self.founder_ids(), *self._members]

    def founder_ids(self) -> list:
        """Ids of the landmarks with a block of their own (founders and landmarks alone), not members."""
        return [i for i in super().landmark_ids if not isinstance(i, OffsetKey)]

    def block(self, landmark_id):
        member = self._members.get(landmark_id)
        return member[1] if member is not None else super().block(landmark_id)

    def founder_of(self, landmark_id):
        """The founder id of a member, else None."""
        member = self._members.get(landmark_id)
        return None if member is None else member[0]

    def members_of(self, founder_id) -> list:
        return [i for i, (f, _) in self._members.items() if f == founder_id]

    @journaled
    def add_member(self, landmark_id, founder_id, block: ArticulatedBlock, offset_cov=None) -> None:
        """Make ``landmark_id`` (not in the state) a member reading the founder's block through ``block``
        (a state that holds offset errors takes ``offset_cov``, their covariance (3, 3); others ignore it)."""
        extra = 3 if getattr(block, "member_offset", False) else 0
        if (landmark_id in self or founder_id in self._members or founder_id not in self
                or block.size != self.block(founder_id).size + extra):
            raise ValueError(f"add_member: landmark {landmark_id!r} must be new and founder {founder_id!r} a block "
                             f"of the same size")
        self._members[landmark_id] = (founder_id, block)

    @journaled
    def repoint_member(self, landmark_id, founder_id) -> None:
        """Make a member read another founder's block (then re-anchor it: its block is still the old one)."""
        self._members[landmark_id] = (founder_id, self._members[landmark_id][1])

    @journaled
    def set_member_block(self, landmark_id, block: ArticulatedBlock) -> None:
        self._members[landmark_id] = (self._members[landmark_id][0], block)

    @journaled
    def remove_member(self, landmark_id) -> None:
        del self._members[landmark_id]

    @journaled
    def remove_landmark(self, landmark_id) -> None:
        """A member's membership, or a block (a founder's members stay, to be re-anchored by the caller)."""
        if landmark_id in self._members:
            self.remove_member(landmark_id)
        else:
            super().remove_landmark(landmark_id)


class BodySlamState(BodyMembers, SlamState):
    """:class:`~stslam.slam.core.SlamState` whose landmark ids may be members aliasing a founder's block.

    A member joining a founder whose structure correction δ is a consider parameter also gets its own
    offset error ε (3,) as one (SPEC 13; the member's offset is a mean of its few points, not exact): an
    :class:`~stslam.slam.blocks.OffsetErrorBlock` under ``OffsetKey(member)``, read after the founder's
    entries (:meth:`indices`); it leaves with the membership, or when the member's view no longer reads it.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._init_members()

    def copy(self) -> BodySlamState:
        other = BodySlamState.__new__(BodySlamState)
        other.__dict__.update(SlamState.copy(self).__dict__)
        other._members = dict(self._members)
        return other

    def indices(self, landmark_id) -> np.ndarray:
        member = self._members.get(landmark_id)
        if member is None:
            return super().indices(landmark_id)
        if getattr(member[1], "member_offset", False):
            return np.concatenate([super().indices(member[0]), super().indices(OffsetKey(landmark_id))])
        return super().indices(member[0])

    @journaled
    def add_member(self, landmark_id, founder_id, block, offset_cov=None) -> None:
        """As :meth:`BodyMembers.add_member`; with ``offset_cov`` and a founder's consider δ, the member's
        offset error ε enters the state: mean 0, covariance ``offset_cov``, uncorrelated with the rest."""
        if offset_cov is None or not getattr(block, "consider", False):
            super().add_member(landmark_id, founder_id, block)
            return
        super().add_member(landmark_id, founder_id, replace(block, member_offset=True))  # (checks the ids)
        self._append(OffsetKey(landmark_id), OffsetErrorBlock(), np.zeros(3), np.zeros((3, 3)),
                     np.asarray(offset_cov, dtype=float))

    @journaled
    def set_member_block(self, landmark_id, block) -> None:
        """A new view for a member (re-anchored): it keeps its offset error while the view can read it."""
        key = OffsetKey(landmark_id)
        if key in self._blocks:
            if getattr(block, "consider", False) and getattr(block, "founder_structure", None) is not None:
                block = replace(block, member_offset=True)
            else:
                SlamState.remove_landmark(self, key)
        super().set_member_block(landmark_id, block)

    @journaled
    def remove_member(self, landmark_id) -> None:
        super().remove_member(landmark_id)
        if OffsetKey(landmark_id) in self._blocks:
            SlamState.remove_landmark(self, OffsetKey(landmark_id))

    def block_q(self, founder_id) -> float:
        """q, the first entry of the founder's motion state at the current frame."""
        member = self._members.get(founder_id)
        start, _ = self._blocks[member[0] if member is not None else founder_id]  # (indices' first entry)
        return float(self.x[start])

    @journaled
    def detach_member(self, landmark_id, block, at=None) -> None:
        """Give a member its own ``block`` (a static point) at its position: m = p_i(X), P by ∂m/∂X
        (m = ``at`` (3,) if given)."""
        m, cov = self.landmark_position(landmark_id)
        m = m if at is None else np.asarray(at, dtype=float)
        _, dm_dx = self.block(landmark_id).position(self.x[self.indices(landmark_id)])
        cross = self.P[:, self.indices(landmark_id)] @ dm_dx.T
        start = self.x.size
        self.x, self.P = ekf.augment(self.x, self.P, m, 0.5 * (cov + cov.T), cross)
        self.remove_member(landmark_id)  # (and its offset error, now carried by the point's covariance)
        self._blocks[landmark_id] = (self.x.size - block.size, block)
        self._groups = self._frozen = None
