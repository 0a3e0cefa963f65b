"""Articulated bodies in A-SLAM: members share one joint and one motion state (SPEC 13).

A body is founded by a landmark converted to an articulated block (its
*founder*, :mod:`stslam.slam.landmark_policy`); the founder's block holds the
body's motion state X = [q, q⁽¹⁾, …] on the founder's structure. Other
landmarks join as *members*: they have no block of their own, only an
:class:`~stslam.slam.blocks.ArticulatedBlock` on their own structure in the
body's q (:func:`stslam.articulation.body.member_structure`) that reads the
founder's slice of the state, so each member's observation updates the body's
q through ∂p_i/∂q (SPEC 13, 5.3). A single landmark is a body of one point.

The states hold the aliasing (:mod:`stslam.slam.body_state`: the EKF's
:class:`BodySlamState`; the factor graph's :class:`stslam.graph.bodies.GraphBodyState`);
:class:`BodyGrouping` holds the rules:

* **Join.** Every ``every`` frames, each landmark seen that is not a member,
  not decided static and not awaiting conversion is tested against each
  founder (``BodySettings``): over their last ``window`` common frames (at
  least ``min_common``) both must have moved more than ``min_motion_m``
  (block means, :class:`~stslam.articulation.body.RigidityTest`: two resting
  points keep their distance too), their distance must stay constant
  (:func:`~stslam.articulation.body.rigidity_test`, χ² p-value above
  ``significance``; a pose error moves both points of a frame rigidly, so only
  the sensor noise enters), and the candidate's points must fit the body's
  motion (:func:`~stslam.articulation.body.member_fit_test`, with R plus the
  pose's J_pose P_pose J_poseᵀ, SPEC 13). A decided articulated candidate of
  the founder's model must also have a joint that agrees (``joint_tolerance``). Of the consistent founders the one with the highest
  p-value is joined; the member's position at q = 0 is fitted from its points
  and the founder's q at those frames (:func:`~stslam.articulation.body.member_offset`).
  A founder with members joins only a body at least as large, and brings its
  members along (bodies merge).
* **Leave.** A member rejected ``restart_after`` times in a row leaves: it is
  re-initialised from its observation as an undecided static point.
* **Refits.** When the founder's block changes (a structure refit, a restart,
  a return to static) its members are carried along: each is re-anchored on
  the new block at its current predicted position; a founder made static
  releases its members as static points at their predicted positions.
"""

from __future__ import annotations

import numpy as np

from stslam.articulation.body import axes_agree, joint_of, member_fit_test, member_offset, member_position, \
    member_structure, rigidity_test
from stslam.geometry import rotation_z
from stslam.robot.sensor import point_from_observation
from stslam.slam.blocks import ArticulatedBlock, CorrectedArticulatedBlock
from stslam.slam.a_slam_settings import ARTICULATED, BodySettings
from stslam.slam.body_state import BodyMembers, BodySlamState
from stslam.slam.decisions import WindowEvidence, preferred_model, revised_model
from stslam.articulation.window_evidence import MIN_WINDOW
from stslam.slam.landmark_policy import LandmarkPolicy

__all__ = ["BodyGrouping", "BodyLandmarkPolicy", "BodyMembers", "BodySettings", "BodySlamState"]


class Sighting:
    """One observation kept for grouping: z (3,) and R (3, 3) in the sensor frame, with the
    posterior pose (3,) and its covariance (3, 3) of its frame."""

    __slots__ = ("z", "R", "pose", "pose_cov", "_world")

    def __init__(self, z, R, pose, pose_cov):
        self.z, self.R, self.pose, self.pose_cov, self._world = z, R, pose, pose_cov, None

    def world(self) -> tuple:
        """World point m (3,), its sensor covariance R_world (3, 3), and R_world plus the pose's share
        J_pose P_pose J_poseᵀ (SPEC 5.2, 13); made on first use."""
        if self._world is None:
            m, J_pose, _ = point_from_observation(self.pose, self.z)  # SPEC 5.2
            rot = rotation_z(self.pose[2])
            R_world = rot @ self.R @ rot.T
            self._world = (m, R_world, R_world + J_pose @ self.pose_cov @ J_pose.T)
        return self._world


class BodyGrouping:
    """The grouping rules of one A-SLAM run (module docstring) over the policy's landmark marks."""

    def __init__(self, settings: BodySettings):
        self.settings = settings
        self.points: dict = {}  # landmark id -> {frame: Sighting}
        self.q: dict = {}  # founder id -> {frame: q of its block}
        self._joints: dict = {}  # founder id -> (its block's structure, joint_of it)

    # ---------------------------------------------------------------- records
    def record(self, state: BodyMembers, k: int, ids, zs, Rs) -> None:
        """Keep the frame's observations with the posterior pose and its covariance (their world points
        are made only when a grouping test needs them, :class:`Sighting`), and every founder's q."""
        pose, pose_cov = state.pose, state.pose_cov
        keep = max(2 * self.settings.window + 10, self.settings.evidence_window)
        for i, z, R in zip(ids, zs, Rs, strict=True):
            track = self.points.setdefault(i, {})
            track[k] = Sighting(np.array(z, dtype=float), R, pose, pose_cov)
            if len(track) > keep:
                del track[min(track)]
        for i in state.founder_ids():
            if isinstance(state.block(i), ArticulatedBlock):
                series = self.q.setdefault(i, {})
                series[k] = state.block_q(i)
                if len(series) > keep:
                    del series[min(series)]

    def forget_q(self, founder_id) -> None:
        """The founder's q was re-initialised: its history no longer applies."""
        self.q.pop(founder_id, None)

    def requalify_q(self, founder_id, old_block, new_block) -> None:
        """Carry the founder's q history onto its refitted structure: q′ = IK(C′, f(C, q)) (SPEC 2)."""
        series = self.q.get(founder_id)
        if not series or not isinstance(new_block, ArticulatedBlock) or new_block.model.name != old_block.model.name:
            self.forget_q(founder_id)
            return
        frames = sorted(series)
        m = old_block.model.position(old_block.structure, np.array([[series[f]] for f in frames]))
        q_new = new_block.model.motion_variable(new_block.structure, m)[:, 0]
        self.q[founder_id] = dict(zip(frames, q_new.tolist()))

    # ------------------------------------------------------------- carry along
    def snapshot(self, state: BodyMembers, founder_id) -> dict:
        """Members' predicted positions before the founder's block changes."""
        return {i: state.landmark_position(i)[0] for i in state.members_of(founder_id)}

    def reanchor(self, state: BodyMembers, founder_id, positions: dict, marks, static_block) -> None:
        """Put each member back on the founder's new block at its position of ``positions``; one too close
        to a new hinge axis leaves as a ``static_block`` point."""
        block = state.block(founder_id)
        for i, m in positions.items():
            joint = joint_of(block.model.name, block.structure)
            q = state.block_q(founder_id)
            try:
                structure = member_structure(joint, member_position(joint, m, q, 0.0))
            except ValueError:  # too close to the new axis: the member leaves as a static point
                state.detach_member(i, static_block)
                _unset(marks[i], "static")
                continue
            state.set_member_block(i, _member_block(block, structure))
            marks[i].structure = structure

    # ---------------------------------------------------------------- joining
    def candidates(self, state: BodyMembers, marks, k: int, ids) -> list:
        """Landmarks seen this frame that may join a body: not members, not decided static, not pending."""
        if k % self.settings.every:
            return []
        return [i for i in ids if i in state and state.founder_of(i) is None
                and marks[i].status != "static" and marks[i].pending is None]

    def best_body(self, state: BodyMembers, landmark_id, mark):
        """(founder id, points (n, 3), founder q (n,)) of the most consistent body, or None."""
        s = self.settings
        own = self.points.get(landmark_id, {})
        best, best_p = None, -1.0
        size = len(state.members_of(landmark_id))
        own_joint = None  # the landmark's joint, made once when a founder of its model asks for it
        for founder, series in self.q.items():
            if founder == landmark_id or founder not in state or state.founder_of(founder) is not None:
                continue
            if size and len(state.members_of(founder)) < size:  # a body merges into one at least as large
                continue
            block = state.block(founder)
            if not isinstance(block, ArticulatedBlock):
                continue
            if mark.status == block.model.name:
                own_joint = own_joint or joint_of(mark.status, mark.structure)
                if not axes_agree(self._founder_joint(founder, block), own_joint, s.joint_tolerance):
                    continue
            theirs = self.points.get(founder, {})
            frames = sorted(set(own) & set(theirs) & set(series))[-s.window:]
            if len(frames) < s.min_common:
                continue
            mine, other = [own[f].world() for f in frames], [theirs[f].world() for f in frames]
            test = rigidity_test([w[0] for w in mine], [w[0] for w in other], [w[1] for w in mine],
                                 [w[1] for w in other])
            if not test.consistent(s.significance, s.min_motion_m) or test.p_value <= best_p:
                continue
            points, qs = np.array([w[0] for w in mine]), np.array([series[f] for f in frames])
            _, p_fit = member_fit_test(joint_of(block.model.name, block.structure), points, qs,
                                       [w[2] for w in mine])
            if p_fit > s.significance:
                best, best_p = (founder, points, qs), test.p_value
        return best

    def _founder_joint(self, founder, block: ArticulatedBlock):
        """joint_of the founder's block, kept while its structure stays (the joint depends on nothing else)."""
        kept = self._joints.get(founder)
        if kept is None or kept[0] is not block.structure:
            kept = self._joints[founder] = (block.structure, joint_of(block.model.name, block.structure))
        return kept[1]

    def join(self, state: BodyMembers, landmark_id, mark, founder, points, qs) -> bool:
        """Make the landmark a member of the founder's body; False when it is too close to the axis."""
        block = state.block(founder)
        joint = joint_of(block.model.name, block.structure)
        try:
            structure = member_structure(joint, member_offset(joint, points, qs))
        except ValueError:
            return False
        state.remove_landmark(landmark_id)
        state.add_member(landmark_id, founder, _member_block(block, structure))
        self.forget_q(landmark_id)
        mark.status, mark.pending, mark.held, mark.structure, mark.body = block.model.name, None, None, structure, founder
        mark.refine_stopped = True  # a member's selector is no longer fed: the body's joint is the founder's
        return True


def _member_block(founder_block: ArticulatedBlock, structure) -> ArticulatedBlock:
    """The member's view of the founder's motion state: the same model, order and size, its own structure
    (fixed: a founder's structure correction is read by the founder only)."""
    if isinstance(founder_block, CorrectedArticulatedBlock):
        return founder_block.member_view(structure)
    return ArticulatedBlock(founder_block.model, structure, founder_block.order, founder_block.sigma_eta,
                            founder_block.sigma_rate0)


def _unset(mark, status: str) -> None:
    """A landmark that left its body: no member structure, its own selector fed again when undecided."""
    mark.status, mark.body, mark.structure, mark.fitted, mark.r_scale = status, None, None, None, 1.0
    mark.refine_stopped = False


class BodyLandmarkPolicy(LandmarkPolicy):
    """:class:`~stslam.slam.landmark_policy.LandmarkPolicy` with bodies (module docstring) on a state
    with :class:`BodyMembers` (:class:`BodySlamState`, or the factor graph's
    :class:`stslam.graph.bodies.GraphBodyState`); on any other state it is the plain policy."""

    def __init__(self, params):
        super().__init__(params)
        self.bodies = BodyGrouping(params.bodies)
        self.evidence = WindowEvidence(lambda i: self.bodies.points.get(i, {}))
        self.revises = params.bodies.revise

    @staticmethod
    def _active(state) -> bool:
        return isinstance(state, BodyMembers)

    def group(self, state, frame) -> None:
        """Record the frame and let landmarks seen in it join bodies (after the frame's update)."""
        if not self._active(state):
            return
        self.bodies.record(state, frame.k, frame.ids, frame.zs, frame.Rs)
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
        (:mod:`stslam.slam.decisions`)."""
        s = self.bodies.settings
        moving = [i for i in state.landmark_ids if isinstance(state.block(i), ArticulatedBlock)]
        links = self.evidence.links(moving, s.significance, s.min_motion_m, s.min_common)
        for founder in state.founder_ids():
            block, mark = state.block(founder), self.marks[founder]
            if not isinstance(block, ArticulatedBlock) or mark.pending is not None:
                continue
            members = state.members_of(founder)
            group = sorted({founder, *links.get(founder, ()), *members})
            linked = {frozenset((a, b)) for a in group for b in links.get(a, ()) if b in group}
            linked |= {frozenset((a, b)) for a in (founder, *members) for b in (founder, *members) if a != b}
            log_odds = self.evidence.group_log_odds(group, linked)
            new = revised_model(block.model.name, log_odds, s.revision_margin)
            structure = None if new not in self.params.convert else self.evidence.structure(founder, new)
            if structure is None:
                continue
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
                _unset(self.marks[i], "undecided")
            self.bodies.forget_q(landmark_id)

    def convert(self, state, landmark_id, z_robot, R, selector_rates: bool = True) -> bool:
        mark = self.marks[landmark_id]
        if self.revises and mark.status not in ARTICULATED and \
                len(self.bodies.points.get(landmark_id, ())) >= MIN_WINDOW:
            log_odds = self.evidence.log_odds(landmark_id)  # the window says how it moves, when it is clear
            clear = abs(log_odds) > self.bodies.settings.revision_margin
            if clear and preferred_model(log_odds) in self.params.convert:
                mark.pending = preferred_model(log_odds)
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
                _unset(self.marks[i], "undecided")
        self._carry(state, landmark_id, lambda: super(BodyLandmarkPolicy, self)._to_static(state, landmark_id))

    def restart(self, state, landmark_id, z_robot, R) -> None:
        """A member rejected ``restart_after`` times leaves its body as an undecided point at z."""
        if not self._active(state) or state.founder_of(landmark_id) is None:
            super().restart(state, landmark_id, z_robot, R)
            return
        mark = self.marks[landmark_id]
        state.remove_member(landmark_id)
        state.add_landmark(landmark_id, self.static_block, z_robot, R)
        _unset(mark, "undecided")
        mark.rejections = 0
        mark.restarts += 1
