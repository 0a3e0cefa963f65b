"""Roll an EKF back to a point's onset and replay the frames since without it (SPEC 6.3, 18).

A point that begins to move slowly passes the gate for a few frames before
A-SLAM's onset test (:func:`stslam.slam.onsets.onsets`) flags it, and while
it is used the filter follows it: when most of the view moves together (a
fridge door), the robot is dragged with it. Holding the point out from the
flag on stops the harm but does not undo it. A filter can: it keeps the last
frames' prior states and the observations each frame's updates used, and when
a point is flagged it restores the state of the frame at which the point's
CUSUM began to rise (Page's estimate of the change point) and redoes every
frame since (prediction, updates, new landmarks) with that point's
observations left out. The poses already recorded stay as they were (the
track is the filter's, frame by frame); the replayed state carries on.

Only the state is replayed, with the decisions the frames took (which
observations passed the gate): model selection, the onset test and the
restarts keep what they saw. The changes of the state's layout the frames
made (a landmark added, converted, restarted, grouped into a body or out of
it: the :func:`~stslam.slam.journal.journaled` methods, which report to the
history as the state's journal) are redone in their place with the same
arguments, so a replay reaches back past them; a change made otherwise ends
the history (:meth:`ReplayHistory.watch`, :meth:`ReplayHistory.check`).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np


@dataclass
class _Entry:
    """One frame: the state after its prediction, and the updates and changes made to it since."""

    k: int
    prior: object
    ops: list = field(default_factory=list)  # ("joint" | "each", ids, zs, Rs) or ("call", method, args, kwargs)


class ReplayHistory:
    """The last ``max_frames`` frames of one EKF run, to roll back to and replay (module docstring).

    Parameters
    ----------
    max_frames : int
        Most frames a replay reaches back (the history kept).
    controls_vw, control_covs, dts_s : numpy.ndarray
        The run's controls (n − 1, 2), their covariances (n − 1, 2, 2) and steps (n − 1,) s,
        as :func:`stslam.slam.loop.run_slam` predicts with them.
    """

    def __init__(self, max_frames: int, controls_vw, control_covs, dts_s):
        self.entries: deque = deque(maxlen=max_frames)
        self.controls, self.control_covs, self.dts = controls_vw, control_covs, dts_s
        self.replays = 0
        self.replayed_frames = 0
        self._mark = None

    # ----------------------------------------------------------- recording
    def begin(self, k: int, state) -> None:
        """Frame k's changes and updates are about to run on ``state`` (predicted): keep a copy of it, and
        become the state's journal (:mod:`stslam.slam.journal`). Once per frame: a second call does nothing."""
        state.journal = self
        if not self.entries or self.entries[-1].k != k:
            self.entries.append(_Entry(k, state.copy()))

    def record(self, kind: str, ids, zs, Rs) -> None:
        """An update the current frame made: ``kind`` "joint" (one joint update) or "each" (one by one)."""
        if self.entries and len(ids):
            self.entries[-1].ops.append((kind, list(ids), np.array(zs), np.array(Rs)))

    def log(self, state, name: str, args: tuple, kwargs: dict) -> None:
        """A journaled change the current frame made to ``state`` (:func:`~stslam.slam.journal.journaled`)."""
        if self.entries:
            self.entries[-1].ops.append(("call", name, args, kwargs))
        if self._mark is not None:  # an expected change: the history stays
            self._mark = _layout(state)

    def watch(self, state) -> None:
        """Remember the state before a step that must not change it (else the history ends)."""
        self._mark = _layout(state)

    def check(self, state) -> None:
        """End the history if the state changed since :meth:`watch`."""
        if self._mark is not None and not _same(self._mark, _layout(state)):
            self.clear()
        self._mark = None

    def clear(self) -> None:
        self.entries.clear()

    # ------------------------------------------------------------- replay
    def replay(self, state, flagged: list, start: int) -> bool:
        """Roll ``state`` back to frame ``start`` (the earliest onset of ``flagged``; the oldest frame kept if
        it lies before them) and redo the frames since without ``flagged``'s observations.

        Changes ``state`` in place (its attributes take the replayed state's) and rewrites the
        history to match; False when no frame since used them.
        """
        if not self.entries:
            return False
        first = next((n for n, e in enumerate(self.entries) if e.k >= start), None)
        drop = set(flagged)
        if first is None or not any(_uses(op, drop) for e in list(self.entries)[first:] for op in e.ops):
            return False
        entries = list(self.entries)[first:]
        work = entries[0].prior.copy()
        for n, entry in enumerate(entries):
            if n:
                for t in range(entries[n - 1].k + 1, entry.k + 1):  # run_slam's predictions, frame by frame
                    work.predict(self.controls[t - 1], self.control_covs[t - 1], float(self.dts[t - 1]))
                entry.prior = work.copy()
            entry.ops = [kept for op in entry.ops if (kept := _without(op, drop)) is not None]
            for op in entry.ops:
                _apply(work, op)
        state.__dict__.update(work.__dict__)  # (the copy has no journal: the state keeps its own)
        self.replays += 1
        self.replayed_frames += len(entries)
        return True


def _layout(state) -> tuple:
    """What identifies a state's contents: its arrays (every change to x or P replaces them) and its
    members' founders and blocks (:class:`~stslam.slam.bodies.state.BodySlamState`), by identity."""
    members = getattr(state, "_members", {})
    return state.x, state.P, {i: (f, id(b)) for i, (f, b) in members.items()}


def _same(a: tuple, b: tuple) -> bool:
    return a[0] is b[0] and a[1] is b[1] and a[2] == b[2]


def _uses(op, drop: set) -> bool:
    return op[0] != "call" and any(i in drop for i in op[1])


def _without(op, drop: set):
    """The update ``op`` without the observations of ``drop`` (None when none is left); changes stay."""
    if not _uses(op, drop):
        return op
    keep = [n for n, i in enumerate(op[1]) if i not in drop]
    if not keep:
        return None
    return op[0], [op[1][n] for n in keep], op[2][keep], op[3][keep]


def _apply(state, op) -> None:
    kind = op[0]
    if kind == "call":
        getattr(state, op[1])(*op[2], **op[3])
    elif kind == "joint":
        state.update_landmarks(op[1], op[2], op[3])
    else:  # the observations the gate passed, one by one again
        state.update_each(op[1], op[2], op[3])
