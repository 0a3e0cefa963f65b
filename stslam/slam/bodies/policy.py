"""A-SLAM's landmark policy with articulated bodies (SPEC 13): a body's members share one joint and one
motion state, and its model is revised as a whole (:mod:`stslam.slam.bodies`)."""

from __future__ import annotations

from stslam.slam.a_slam_settings import ARTICULATED
from stslam.slam.blocks import ArticulatedBlock
from stslam.slam.bodies.decisions import WindowEvidence, body_revisions, conversion_model
from stslam.slam.bodies.grouping import BodyGrouping, unset_body
from stslam.slam.bodies.state import BodyMembers
from stslam.slam.landmark_policy import LandmarkPolicy

__all__ = ["BodyLandmarkPolicy"]


class BodyLandmarkPolicy(LandmarkPolicy):
    """:class:`~stslam.slam.landmark_policy.LandmarkPolicy` with bodies (:mod:`stslam.slam.bodies`) on a
    state with :class:`~stslam.slam.bodies.state.BodyMembers` (the EKF's
    :class:`~stslam.slam.bodies.state.BodySlamState`, or the factor graph's
    :class:`stslam.graph.bodies.GraphBodyState`); on any other state it is the plain policy."""

    def __init__(self, params):
        super().__init__(params)
        self.bodies = BodyGrouping(params.bodies)
        self.evidence = WindowEvidence(lambda i: self.bodies.points.get(i, {}))
        self.revises = params.bodies.revise

    @staticmethod
    def _active(state) -> bool:
        return isinstance(state, BodyMembers)

    def group(self, state, frame, pose=None) -> None:
        """Record the frame and let landmarks seen in it join bodies (after the frame's update); ``pose``
        (pose (3,), covariance (3, 3)), if given, maps the frame's sightings instead of the state's pose."""
        if not self._active(state):
            return
        self.bodies.record(state, frame.k, frame.ids, frame.zs, frame.Rs, pose)
        for i in self.bodies.candidates(state, self.marks, frame.k, frame.ids):
            if state.founder_of(i) is not None:  # it joined a body earlier in this pass
                continue
            mark = self.marks[i]
            if not self._seen_moving(mark):
                continue
            found = self.bodies.best_body(state, i, mark)
            if found is None:
                continue
            members = self.bodies.snapshot(state, i)  # a body joining another brings its members along
            if self.bodies.join(state, i, mark, *found):
                mark.r_scale = self.marks[found[0]].fixed_scale  # its structure is held fixed
                mark.decisions.append((frame.k, mark.n_fed + mark.selector.n_observations - 1, mark.status))
                for j in members:
                    state.repoint_member(j, found[0])
                    self.marks[j].body = found[0]
                self.bodies.reanchor(state, found[0], members, self.marks, self.static_block)
        if self.revises and frame.k % self.bodies.settings.every == 0:
            self.revise(state, frame.k)

    def revise(self, state, k: int) -> None:
        """Switch each articulated body whose pooled window evidence favours the other moving model
        (:func:`~stslam.slam.bodies.decisions.body_revisions`)."""
        bodies = {founder: (block.model.name, state.members_of(founder), self.marks[founder].pending is not None)
                  for founder in state.founder_ids()
                  if isinstance(block := state.block(founder), ArticulatedBlock)}
        moving = [i for i in state.landmark_ids if isinstance(state.block(i), ArticulatedBlock)]
        for founder, new, structure in body_revisions(self.evidence, bodies, moving, self.bodies.settings,
                                                      self.params.convert):
            mark = self.marks[founder]
            self._rebase(state, founder, new, structure)
            mark.revisions += 1
            mark.decisions.append((k, mark.n_fed + mark.selector.n_observations - 1, new))
            for i in state.members_of(founder):
                self.marks[i].status = new

    def _seen_moving(self, mark) -> bool:
        """Whether the landmark's own track has moved significantly: its selector's motion test at
        ``support_alpha``, with each point's covariance (SPEC 13). A point still held static keeps its
        distance to a body that moves across the line between them, so the rigidity test cannot tell."""
        alpha = self.params.selection.support_alpha
        return alpha is None or mark.selector.motion_p_value() < alpha

    def _carry(self, state, landmark_id, change, refit: bool = False) -> None:
        """Run ``change()`` on a founder's block and carry its members (and, for a ``refit``, its q history)
        along."""
        if not self._active(state):
            change()
            return
        old = state.block(landmark_id) if landmark_id in state else None
        positions = self.bodies.snapshot(state, landmark_id)
        change()
        new = state.block(landmark_id) if landmark_id in state else None
        if refit and isinstance(old, ArticulatedBlock):
            self.bodies.requalify_q(landmark_id, old, new)
        else:
            self.bodies.forget_q(landmark_id)
        if not positions:
            return
        if isinstance(new, ArticulatedBlock):
            self.bodies.reanchor(state, landmark_id, positions, self.marks, self.static_block)
        else:  # a founder made static releases its members as static points
            for i in positions:
                state.detach_member(i, self.static_block)
                unset_body(self.marks[i], "undecided")
            self.bodies.forget_q(landmark_id)

    def convert(self, state, landmark_id, z_robot, R, selector_rates: bool = True) -> bool:
        mark = self.marks[landmark_id]
        if self.revises and mark.status not in ARTICULATED:  # the window says how it moves, when it is clear
            mark.pending = conversion_model(self.evidence, landmark_id, mark.pending,
                                            self.bodies.settings.revision_margin, self.params.convert)
        done = []
        self._carry(state, landmark_id, lambda: done.append(super(BodyLandmarkPolicy, self).convert(
            state, landmark_id, z_robot, R, selector_rates)))
        return done[0]

    def _rebase(self, state, landmark_id, name: str, structure=None) -> None:
        self._carry(state, landmark_id,
                    lambda: super(BodyLandmarkPolicy, self)._rebase(state, landmark_id, name, structure), refit=True)

    def _settle(self, state, landmark_id) -> None:
        self._carry(state, landmark_id, lambda: super(BodyLandmarkPolicy, self)._settle(state, landmark_id),
                    refit=True)

    def _to_static(self, state, landmark_id) -> None:
        """A founder made static first releases its members as static points at their positions on the
        body's motion state (read after the change, that state would be the founder's point)."""
        if self._active(state):
            for i in state.members_of(landmark_id):
                state.detach_member(i, self.static_block)
                unset_body(self.marks[i], "undecided")
        self._carry(state, landmark_id, lambda: super(BodyLandmarkPolicy, self)._to_static(state, landmark_id))

    def restart(self, state, landmark_id, z_robot, R) -> None:
        """A member rejected ``restart_after`` times leaves its body as an undecided point at z."""
        if not self._active(state) or state.founder_of(landmark_id) is None:
            super().restart(state, landmark_id, z_robot, R)
            return
        mark = self.marks[landmark_id]
        state.remove_member(landmark_id)
        state.add_landmark(landmark_id, self.static_block, z_robot, R)
        unset_body(mark, "undecided")
        mark.rejections = 0
        mark.restarts += 1
