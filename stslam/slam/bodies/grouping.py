"""Who belongs to which body: the grouping rules of A-SLAM's articulated bodies (SPEC 13).

:class:`BodyGrouping` keeps each landmark's recent sightings (:class:`Sighting`) and holds the rules:

* **Join.** Every ``every`` frames, each landmark seen that is not a member,
  not decided static and not awaiting conversion is tested against each
  founder (``BodySettings``): over their last ``window`` common frames (at
  least ``min_common``) both must have moved more than ``min_motion_m``
  (block means, :class:`~stslam.slam.bodies.joint.RigidityTest`: two resting
  points keep their distance too), their distance must stay constant
  (:func:`~stslam.slam.bodies.joint.rigidity_test`, χ² p-value above
  ``significance``; a pose error moves both points of a frame rigidly, so only
  the sensor noise enters), they must have moved at the same times
  (:func:`~stslam.slam.bodies.decisions.co_moving`: a distance changes only at
  second order when two parts move across the line between them, as the
  kitchen's dishwasher door and top drawer on one wall do), and the candidate's points must fit the body's
  motion (:func:`~stslam.slam.bodies.joint.member_fit_test`, with R plus the
  pose's J_pose P_pose J_poseᵀ, SPEC 13). A decided articulated candidate of
  the founder's model must also have a joint that agrees (``joint_tolerance``). Of the consistent founders the one with the highest
  p-value is joined; the member's position at q = 0 is fitted from its points
  and the founder's q at those frames (:func:`~stslam.slam.bodies.joint.member_offset`).
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

from stslam.geometry import rotation_z
from stslam.robot.sensor import point_from_observation
from stslam.slam.a_slam_settings import BodySettings
from stslam.slam.blocks import ArticulatedBlock, CorrectedArticulatedBlock
from stslam.slam.bodies.joint import axes_agree, joint_of, member_fit_test, member_offset, member_offset_covariance, \
    member_position, off_axis, member_structure, rigidity_test
from stslam.slam.bodies.decisions import co_moving
from stslam.slam.bodies.state import BodyMembers

__all__ = ["BodyGrouping", "Sighting", "unset_body"]


def unset_body(mark, status: str) -> None:
    """A landmark that left its body: no member structure, its own selector fed again when undecided."""
    mark.status, mark.body, mark.structure, mark.fitted, mark.r_scale = status, None, None, None, 1.0
    mark.refine_stopped = False


class Sighting:
    """One observation kept for grouping: z (3,) and R (3, 3) in the sensor frame, with a pose (3,) of
    its frame and that pose's covariance (3, 3) (:meth:`BodyGrouping.record`)."""

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
    def record(self, state: BodyMembers, k: int, ids, zs, Rs, pose=None) -> None:
        """Keep the frame's observations with ``pose`` (pose (3,), covariance (3, 3); None: the state's
        posterior pose) (their world points are made only when a grouping test needs them,
        :class:`Sighting`), and every founder's q."""
        pose, pose_cov = (state.pose, state.pose_cov) if pose is None else pose
        keep = max(2 * self.settings.window + 10, self.settings.evidence_window)
        for i, z, R in zip(ids, zs, Rs, strict=True):
            track = self.points.setdefault(i, {})
            track[k] = Sighting(np.array(z, dtype=float), R, pose, pose_cov)
            if len(track) > keep:  # frames are added in order: the first key is the oldest
                del track[next(iter(track))]
        for i in state.founder_ids():
            if isinstance(state.block(i), ArticulatedBlock):
                series = self.q.setdefault(i, {})
                series[k] = state.block_q(i)
                if len(series) > keep:
                    del series[next(iter(series))]

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
        return {i: state.landmark_point(i) for i in state.members_of(founder_id)}

    def reanchor(self, state: BodyMembers, founder_id, positions: dict, marks, static_block) -> None:
        """Put each member back on the founder's new block at its position of ``positions``; one too close
        to a new hinge axis leaves as a ``static_block`` point."""
        block = state.block(founder_id)
        for i, m in positions.items():
            joint = joint_of(block.model.name, block.structure)
            q = state.block_q(founder_id)
            p_zero = member_position(joint, m, q, 0.0)
            try:
                structure = member_structure(joint, p_zero)
            except ValueError:  # too close to the new axis: the member leaves as a static point at m. Its
                # covariance is read through a view of the founder's new block (its size may have changed)
                # on the nearest circle member_structure accepts (≤ MIN_RADIUS_M off: it barely turns).
                state.set_member_block(i, _member_block(block, member_structure(joint, off_axis(joint, p_zero))))
                state.detach_member(i, static_block, at=m)
                unset_body(marks[i], "static")
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
        """(founder id, points (n, 3), founder q (n,), frames (n,)) of the most consistent body, or None."""
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
            points, others = np.array([w[0] for w in mine]), np.array([w[0] for w in other])
            test = rigidity_test(points, others, [w[1] for w in mine], [w[1] for w in other])
            if not test.consistent(s.significance, s.min_motion_m) or test.p_value <= best_p:
                continue
            if not co_moving(points, others):
                continue
            qs = np.array([series[f] for f in frames])
            _, p_fit = member_fit_test(joint_of(block.model.name, block.structure), points, qs,
                                       [w[2] for w in mine])
            if p_fit > s.significance:
                best, best_p = (founder, points, qs, frames), test.p_value
        return best

    def _founder_joint(self, founder, block: ArticulatedBlock):
        """joint_of the founder's block, kept while its structure stays (the joint depends on nothing else)."""
        kept = self._joints.get(founder)
        if kept is None or kept[0] is not block.structure:
            kept = self._joints[founder] = (block.structure, joint_of(block.model.name, block.structure))
        return kept[1]

    def join(self, state: BodyMembers, landmark_id, mark, founder, points, qs, frames) -> bool:
        """Make the landmark a member of the founder's body; False when it is too close to the axis.
        The covariance of its offset (from its sightings at ``frames``) goes with it, for a state that
        keeps offset errors."""
        block = state.block(founder)
        joint = joint_of(block.model.name, block.structure)
        try:
            structure = member_structure(joint, member_offset(joint, points, qs))
        except ValueError:
            return False
        worlds = [self.points[landmark_id][f].world() for f in frames]
        offset_cov = member_offset_covariance(joint, qs, [w[1] for w in worlds], [w[2] - w[1] for w in worlds])
        state.remove_landmark(landmark_id)
        state.add_member(landmark_id, founder, _member_block(block, structure), offset_cov)
        self.forget_q(landmark_id)
        mark.status, mark.pending, mark.held, mark.structure, mark.body = block.model.name, None, None, structure, founder
        mark.refine_stopped = True  # a member's selector is no longer fed: the body's joint is the founder's
        return True


def _member_block(founder_block: ArticulatedBlock, structure) -> ArticulatedBlock:
    """The member's view of the founder's motion state: the same model, order and size, its own structure
    (and, for a founder with a structure correction δ, the part of δ that moves the shared joint)."""
    if isinstance(founder_block, CorrectedArticulatedBlock):
        return founder_block.member_view(structure)
    return ArticulatedBlock(founder_block.model, structure, founder_block.order, founder_block.sigma_eta,
                            founder_block.sigma_rate0)
