"""Which model a landmark or a body is, and when it switches: every decision of A-SLAM in one place
(SPEC 4, 6.3, 13, 16, 18).

The evidence comes from elsewhere; the decisions are all made here, as pure functions of it.
The policies (:class:`~stslam.slam.landmark_policy.LandmarkPolicy`, with bodies
:class:`~stslam.slam.bodies.policy.BodyLandmarkPolicy`) carry out what these functions return,
on either back end (the EKF's :class:`~stslam.slam.bodies.state.BodySlamState` or the factor
graph's :class:`~stslam.graph.bodies.GraphBodyState`).

1. **The selector's verdict** (:func:`selector_action`). A landmark's online selector
   (:class:`~stslam.selection.selector.ModelSelector`, Algorithm 1, SPEC 4) holds a model for
   ``hold_steps`` observations. That verdict makes an undecided or static point articulated
   (a conversion at its next sighting), an articulated one static again if it was never seen
   moving (SPEC 16) and the verdict has stood ``static_hold`` observations, or is only recorded (a
   model not in ``convert``). Between the two
   moving models the window below has the last word once revisions are on.
2. **Evidence of a window.** Each landmark keeps its latest ``evidence_window`` sightings,
   mapped to the world with their frame's pose and weighted by their covariance with the
   pose's share (SPEC 5.2, 13). Under the EKF that pose is the one the frame's static points
   alone left (``BodySettings.evidence_pose``): a body's own updates cannot then bend the
   pose towards its current model and so confirm it. Its window's revolute : prismatic log-odds is the BIC
   difference of a circle and a line fitted to it
   (:func:`stslam.articulation.window_evidence.revolute_log_odds`); a body's members share one
   joint, so their log-odds add, and each pair of points that move rigidly together votes by
   whether the vector between them turned (:class:`WindowEvidence`).
3. **Conversion** (:func:`conversion_model`). When the selector calls a landmark articulated,
   the model it converts to is the one its own window favours when the window is clear (the
   selector says *that* it moves; the window says *how*).
4. **Revision** (:func:`body_revisions`). Every ``every`` frames each articulated body (a
   founder with its members, or a landmark alone: a body of one) whose pooled log-odds favour
   the other moving model by more than ``revision_margin`` switches to it, however late. The
   new block's structure is fitted to the founder's whole window, its motion state carried
   over by re-basing (same position, its cross-covariances mapped by the Jacobian:
   :mod:`stslam.articulation.rebase`), and the members are re-anchored on the new joint.
   Static ↔ articulated stays with the selector (SPEC 16: never back to static once seen moving).

Who joins which body is a test of rigidity, not a model decision: :mod:`stslam.slam.bodies.grouping`.
"""

from __future__ import annotations

import numpy as np

from stslam.slam.a_slam_settings import ARTICULATED
from stslam.slam.bodies.joint import SPREAD_BLOCK, RigidityTest
from stslam.slam.bodies.pair_kernels import co_moving_kernel, common_frames, pair_link
from stslam.articulation.window_evidence import (MIN_WINDOW, PairTurn, quiet_log_odds, revolute_log_odds, turn_evidence,
                                                 window_fit)

__all__ = ["WindowEvidence", "body_revisions", "conversion_model", "preferred_model", "revised_model",
           "selector_action"]


def preferred_model(log_odds: float) -> str:
    """The moving model a revolute : prismatic log-odds favours (ties: prismatic, the simpler)."""
    return "revolute" if log_odds > 0.0 else "prismatic"


def revised_model(current: str, log_odds: float, margin: float) -> str | None:
    """The model a body on ``current`` switches to, or None: the pooled log-odds must favour the other
    by more than ``margin`` (hysteresis, so that evidence hovering near even does not flap)."""
    if current == "prismatic" and log_odds > margin:
        return "revolute"
    if current == "revolute" and log_odds < -margin:
        return "prismatic"
    return None


POINT_WEIGHT = 0.5  # a point's window log-odds counts half in a group: its BIC takes the pose's slow
                    # error, which bends a slide, for curvature (per-window decisions with the true poses
                    # were right 77% of the time, with the estimated ones less)
CO_MOTION_BLOCK = 5  # observations averaged per step of the co-motion test
CO_MOTION_CORRELATION = 0.9  # how alike two points' departures from their first position must be


def co_moving(points_a, points_b) -> bool:
    """Whether two tracks at the same frames moved at the same times: the distances of their block
    means (``CO_MOTION_BLOCK`` observations) from their first block rise and fall together (Pearson
    correlation above ``CO_MOTION_CORRELATION``). Two points of one part do, however far each is
    from the hinge; two drawers that move in turn do not, and a distance test alone can pass them
    when each slides across the line between them."""
    a, b = np.asarray(points_a, dtype=float).reshape(-1, 3), np.asarray(points_b, dtype=float).reshape(-1, 3)
    if a.shape != b.shape:
        raise ValueError(f"co_moving: two tracks at the same frames, got shapes {a.shape} and {b.shape}")
    return bool(co_moving_kernel(a, b, CO_MOTION_BLOCK, CO_MOTION_CORRELATION))


def _window_rows(track: dict, frames: list) -> tuple:
    """Frames (n,), world points (n, 3), sensor covariances (n, 3, 3) and per-axis variances with the
    pose's share (n,) of the sightings ``track[f]`` for f in ``frames`` (SPEC 5.2, 13)."""
    worlds = [track[f].world() for f in frames]
    shares = np.array([w[2] for w in worlds], dtype=float).reshape(-1, 3, 3)
    return (np.array(frames, dtype=int), np.array([w[0] for w in worlds], dtype=float).reshape(-1, 3),
            np.array([w[1] for w in worlds], dtype=float).reshape(-1, 3, 3),
            (shares[:, 0, 0] + shares[:, 1, 1] + shares[:, 2, 2]) / 3.0)  # trace / 3


class WindowEvidence:
    """Per landmark, the log-odds of its kept window, recomputed only when the window has changed.

    ``sightings(landmark_id)`` gives the landmark's kept sightings ({frame: Sighting}, whose
    ``world()`` is (m, R_world, R_world + pose share)).
    """

    def __init__(self, sightings):
        self._sightings = sightings
        self._cache: dict = {}  # id -> (window key, log-odds)
        self._windows: dict = {}  # id -> (window key, frames, points, covariances, variances)
        self._pairs: dict = {}  # (a, b) -> (both window keys, linked, (refuting, PairTurn) or None)

    def size(self, landmark_id) -> int:
        """How many sightings the landmark's window holds."""
        return len(self._sightings(landmark_id))

    def window(self, landmark_id) -> tuple[np.ndarray, np.ndarray]:
        """World points (n, 3) of the kept window and their per-axis variances (n,) (m²)."""
        _, points, _, variances = self._arrays(landmark_id)
        return points, variances

    def _arrays(self, landmark_id, key=None) -> tuple:
        """The kept window's frames (n,), world points (n, 3), sensor covariances (n, 3, 3) and per-axis
        variances with the pose's share (n,), made once per window (see :meth:`_key`; ``key``, if given, is
        its current value). A changed window keeps the rows of the frames it still holds and adds the new
        sightings' rows (sightings are added at the newest end and dropped from the oldest)."""
        key = self._key(landmark_id) if key is None else key
        kept = self._windows.get(landmark_id)
        if kept is not None and kept[0] == key:
            return kept[1:]
        track = self._sightings(landmark_id) or {}
        if kept is not None and kept[1].size and track:
            start = int(np.searchsorted(kept[1], next(iter(track))))  # the oldest frame still kept
            last, fresh = int(kept[1][-1]), []
            for frame in reversed(track):  # the frames after the last one kept, newest first
                if frame <= last:
                    break
                fresh.append(frame)
            fresh.reverse()
            rows = tuple(np.concatenate([old[start:], new])
                         for old, new in zip(kept[1:], _window_rows(track, fresh), strict=True))
            if rows[0].size == len(track) and rows[0][0] == next(iter(track)):
                self._windows[landmark_id] = (key, *rows)
                return rows
        rows = _window_rows(track, sorted(track))  # the first window, or one not grown as above
        self._windows[landmark_id] = (key, *rows)
        return rows

    def _key(self, landmark_id) -> tuple:
        """What the landmark's kept window depends on: its latest frame and its length (sightings are only
        added, in frame order, and dropped from the oldest end: the dict's last key is its latest frame)."""
        track = self._sightings(landmark_id)
        return (next(reversed(track)), len(track)) if track else (None, 0)

    def log_odds(self, landmark_id) -> float:
        key = self._key(landmark_id)
        kept = self._cache.get(landmark_id)
        if kept is None or kept[0] != key:
            kept = self._cache[landmark_id] = (key, revolute_log_odds(*self.window(landmark_id)))
        return kept[1]

    def pooled(self, landmark_ids) -> float:
        """A body's log-odds: the sum over its points (they share one joint, SPEC 13)."""
        return float(sum(self.log_odds(i) for i in landmark_ids))

    def common(self, a, b) -> tuple:
        """World points and sensor covariances of landmarks ``a`` and ``b`` at their common kept frames."""
        frames_a, points_a, covs_a, _ = self._arrays(a)
        frames_b, points_b, covs_b, _ = self._arrays(b)
        ia, ib = common_frames(frames_a, frames_b)  # both sorted, unique
        return points_a[ia], points_b[ib], covs_a[ia], covs_b[ib]

    def links(self, landmark_ids, significance: float, min_motion_m: float, min_common: int) -> dict:
        """Landmark id → the others it moves rigidly with: over their common kept frames (at least
        ``min_common``) both moved more than ``min_motion_m`` and their distance stayed constant
        (:func:`~stslam.slam.bodies.joint.rigidity_test` at ``significance``). Evidence links are not
        the filter's bodies: a door whose points were given a wrong joint cannot join its founder's
        body, but its points still move rigidly together. Links are pairwise, not chained: two
        drawers resting while the other moves can each look rigid with a third point."""
        ids = sorted(landmark_ids)
        out = {i: set() for i in ids}
        keys = {i: self._key(i) for i in ids}  # each window's key once, not once per pair
        for n, a in enumerate(ids):
            for b in ids[n + 1:]:
                key = (keys[a], keys[b])
                kept = self._pairs.get((a, b))
                if kept is None or kept[0] != key or kept[1] is None:  # else: neither window changed
                    frames_a, points_a, covs_a, _ = self._arrays(a, keys[a])
                    frames_b, points_b, covs_b, _ = self._arrays(b, keys[b])
                    candidate, statistic, dof, spread = pair_link(  # common frames, co_moving, rigidity_test
                        frames_a, points_a, covs_a, frames_b, points_b, covs_b, min_common, CO_MOTION_BLOCK,
                        CO_MOTION_CORRELATION, SPREAD_BLOCK)
                    linked = bool(candidate) and RigidityTest.of(statistic, dof, spread).consistent(
                        significance, min_motion_m)
                    kept = self._pairs[(a, b)] = (key, linked, kept[2] if kept is not None and kept[0] == key else None)
                if kept[1]:
                    out[a].add(b)
                    out[b].add(a)
        return out

    def _turn(self, a, b, keys: dict, settings=None) -> PairTurn:
        """turn_evidence of the pair, kept while neither window changes (``keys``: id → :meth:`_key`).

        With ``settings`` (:class:`~stslam.slam.a_slam_settings.BodySettings`), a pair that its common
        frames (at least ``min_common``) show not to be of one rigid body says nothing, whatever grouping
        said: two points of one part move at the same times (:func:`co_moving`) and keep their distance
        (the rigidity test at ``significance``). A dishwasher point grouped with a drawer (kitchen seed
        1014) would otherwise vote for a turn with every drawer point: their difference changes as either
        part moves, while their distance, 2 m across both motions, hardly does.
        """
        a, b = min(a, b), max(a, b)
        key, refuting = (keys[a], keys[b]), settings is not None
        kept = self._pairs.get((a, b))
        if kept is not None and kept[0] == key and kept[2] is not None and kept[2][0] == refuting:
            return kept[2][1]
        common = self.common(a, b)
        value = turn_evidence(*common)
        if value.log_odds and refuting and common[0].shape[0] >= settings.min_common:
            # the links' own test (pair_link): enough common frames, so False means not co-moving
            candidate, statistic, dof, spread = pair_link(*self._arrays(a, keys[a])[:3], *self._arrays(b, keys[b])[:3],
                                                          settings.min_common, CO_MOTION_BLOCK, CO_MOTION_CORRELATION,
                                                          SPREAD_BLOCK)
            if not candidate or RigidityTest.of(statistic, dof, spread).p_value < settings.significance:
                value = PairTurn(0.0, value.offset)
        self._pairs[(a, b)] = (key, kept[1] if kept is not None and kept[0] == key else None, (refuting, value))
        return value

    def group_log_odds(self, group, linked, settings=None) -> float:
        """Revolute : prismatic log-odds of a group of points sharing one joint: their windows'
        log-odds, plus, for each ``linked`` pair (a set of frozensets), whether their difference turned
        (:func:`~stslam.articulation.window_evidence.turn_evidence`; pairs that stayed put count
        together, :func:`~stslam.articulation.window_evidence.quiet_log_odds`; with ``settings``, pairs
        shown not to be of one body say nothing, :meth:`_turn`)."""
        total = POINT_WEIGHT * self.pooled(group)
        quiet, keys = [], {i: self._key(i) for i in group}  # each window's key once, not once per pair
        for n, a in enumerate(group):
            for b in group[n + 1:]:
                if frozenset((a, b)) in linked:
                    turn = self._turn(a, b, keys, settings)
                    if turn.log_odds < 0.0:
                        quiet.append(turn)
                    else:
                        total += turn.log_odds
        return total + quiet_log_odds(quiet)

    def structure(self, landmark_id, model_name: str):
        """Model ``model_name``'s structure fitted to the landmark's whole kept window (None if it cannot be)."""
        points, _ = self.window(landmark_id)
        return window_fit(model_name, points) if len(points) >= 3 else None


# ---------------------------------------------------------------------- the decisions

def selector_action(model: str, status: str, best: str | None, seen_moving: bool, convert, revises: bool,
                    held_steps: int = 1, static_hold: int = 1) -> str | None:
    """What the selector's held verdict ``best`` does to a landmark whose model is ``model`` and whose block is
    ``status`` (SPEC 4, 6.3, 16).

    None: nothing (no verdict, the same model, static for a landmark ``seen_moving``, static for an
    articulated block while the verdict has stood fewer than ``static_hold`` observations (``held_steps``),
    or, for an articulated landmark, the other moving model when that is not in ``convert`` or when the
    window decides between them, ``revises``); ``"static"``: it is a static point again; ``"hold"``: a model
    not in ``convert``, recorded only; ``"rebase"``: an articulated block takes the other moving model
    now; ``"convert"``: an undecided or static point becomes articulated at its next sighting.
    """
    if best is None or best == model or (seen_moving and best == "static"):
        return None
    if best in ARTICULATED and status in ARTICULATED and (best not in convert or revises):
        return None
    if best == "static":
        return "static" if status not in ARTICULATED or held_steps >= static_hold else None
    if best not in convert:
        return "hold"
    return "rebase" if status in ARTICULATED else "convert"


def conversion_model(evidence: WindowEvidence, landmark_id, pending: str, margin: float, convert) -> str:
    """The moving model a landmark the selector called ``pending`` converts to: its window's when that
    is clear (|log-odds| above ``margin``, and a model in ``convert``), else ``pending``."""
    if evidence.size(landmark_id) < MIN_WINDOW:
        return pending
    log_odds = evidence.log_odds(landmark_id)
    chosen = preferred_model(log_odds)
    return chosen if abs(log_odds) > margin and chosen in convert else pending


def body_revisions(evidence: WindowEvidence, bodies, moving, settings, convert) -> list:
    """The bodies whose model switches now: [(founder, new model, its structure)].

    ``bodies`` maps each founder id to (its block's model name, its members, whether a conversion is
    pending); ``moving`` are the ids of every landmark held articulated (points linked to a body by
    :meth:`WindowEvidence.links` vote with it even when they are not its members); ``settings`` is
    :class:`~stslam.slam.a_slam_settings.BodySettings`.
    """
    links = evidence.links(moving, settings.significance, settings.min_motion_m, settings.min_common)
    out = []
    for founder, (current, members, pending) in bodies.items():
        if pending:
            continue
        group = sorted({founder, *links.get(founder, ()), *members})
        body = (founder, *members)
        linked = {frozenset((a, b)) for a in group for b in links.get(a, ()) if b in group}
        linked |= {frozenset((a, b)) for a in body for b in body if a != b}
        new = revised_model(current, evidence.group_log_odds(group, linked, settings), settings.revision_margin)
        structure = None if new not in convert else evidence.structure(founder, new)
        if structure is not None:
            out.append((founder, new, structure))
    return out
