"""A frame's prior marginals without an iSAM2 update: variables made as predictions (SPEC 3, 5.1, 14).

Within a frame :class:`~stslam.graph.state.GraphState` makes the new pose x_k = g(x_{k−1}, u) and
carries each observed landmark's block to the frame, X_t = F X_s + w, before any observation of
the frame is a factor. Both are predictions x_new = F x_src + w, w ~ N(0, Q) (Q with the floor
its factor's noise model adds), from a variable iSAM2 already holds. Their joint marginal is the
EKF's prediction of that part of the state,

    P_new = T P_src Tᵀ + Q,   T = blockdiag(F) placed at each prediction's source,

so the frame's gates can all read its prior marginals from one joint marginal of the sources
(iSAM2's, with no update), and the frame's factors go to iSAM2 in one update. A prediction
from a variable itself predicted in the same frame is composed: F₂F₁, F₂Q₁F₂ᵀ + Q₂.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


class Predictions:
    """The variables made since the last iSAM2 update as predictions: key → (source key, F, Q)."""

    def __init__(self, floor_sigma: float):
        self.floor_sigma = floor_sigma
        self._made: dict = {}

    def __contains__(self, key) -> bool:
        return key in self._made

    def record(self, new, source, F, Q, source_buffered: bool) -> None:
        """``new`` = F x_source + w, Cov w = Q + floor² I (its factor's noise). A source made since the
        update but not as a prediction (``source_buffered``) leaves ``new`` unrecorded: its marginal needs
        the update."""
        Q = np.asarray(Q, dtype=float)
        Q = 0.5 * (Q + Q.T) + self.floor_sigma**2 * np.eye(Q.shape[0])
        F = np.asarray(F, dtype=float)
        if source in self._made:
            base, F0, Q0 = self._made[source]
            self._made[new] = (base, None if F0 is None else F @ F0, F @ Q0 @ F.T + Q)
        elif not source_buffered:
            self._made[new] = (source, F, Q)

    def record_prior(self, new, cov) -> None:
        """``new`` has a prior of covariance ``cov`` and no other factor (a structure's correction δ at its
        first reading): its marginal is that, uncorrelated with every other variable."""
        self._made[new] = (None, None, np.asarray(cov, dtype=float))

    def covers(self, keys, buffered: Callable) -> bool:
        """Whether every key is held by iSAM2 (not ``buffered(key)``) or a recorded prediction."""
        return all(k in self._made or not buffered(k) for k in keys)

    def joint(self, keys, source_joint: Callable, size: Callable) -> np.ndarray:
        """T P_src Tᵀ + Q of ``keys`` (module docstring); ``source_joint(keys)`` is iSAM2's joint marginal,
        ``size(key)`` a variable's dimension."""
        sources = [s for s in dict.fromkeys(self._made[k][0] if k in self._made else k for k in keys) if s is not None]
        source_at = slices([size(k) for k in sources])
        at = dict(zip(sources, source_at, strict=True))
        rows = slices([size(k) for k in keys])
        T = np.zeros((sum(r.size for r in rows), sum(r.size for r in source_at)))
        Q = np.zeros((T.shape[0], T.shape[0]))
        for key, r in zip(keys, rows, strict=True):
            if key in self._made:
                source, F, Q_k = self._made[key]
                if source is not None:
                    T[np.ix_(r, at[source])] = F
                Q[np.ix_(r, r)] = Q_k
            else:
                T[np.ix_(r, at[key])] = np.eye(r.size)
        return (T @ source_joint(sources) @ T.T if sources else 0.0) + Q


class HeldJoints:
    """iSAM2's joint marginals between two of its updates: the last one computed serves every request it
    covers (cut from it, the same numbers to rounding); one it does not cover is computed over its keys
    and ``more()``'s, the variables the frame's other gates are likely to ask for (:func:`near_keys`), so
    that a frame's gates and selection covariances cost one joint marginal where they cost one each."""

    def __init__(self):
        self._last = None  # (key -> rows, P)

    def clear(self) -> None:
        """Forget the last joint marginal (iSAM2 has updated)."""
        self._last = None

    def joint(self, keys, compute: Callable, size: Callable, more: Callable) -> np.ndarray:
        """The joint marginal of ``keys``; ``compute(keys)`` is iSAM2's, ``size(key)`` a variable's dimension."""
        keys = list(keys)
        if self._last is None or not all(k in self._last[0] for k in keys):
            wanted = list(dict.fromkeys([*keys, *more()]))
            self._last = (dict(zip(wanted, slices([size(k) for k in wanted]), strict=True)), compute(wanted))
        at, P = self._last
        rows = np.concatenate([at[k] for k in keys])
        return P[np.ix_(rows, rows)]


def near_keys(state) -> list:
    """The variables iSAM2 holds that a gate of this frame or the next may ask for: the last two poses, the
    latest variable of every landmark seen at this frame or the last, and its structure's δ."""
    from stslam.graph.state import pose_key

    near = [pose_key(k) for k in (state.k - 1, state.k) if k >= 0]
    for key, frame, block in state._heads.values():
        if frame >= state.k - 1:
            near += [key, state._structures.existing(block)]
    return [k for k in near if k is not None and state._solver.holds(k)]


def slices(sizes) -> list:
    """Consecutive index ranges of blocks of these sizes (a joint marginal's rows per variable)."""
    ends = np.cumsum(sizes)
    return [np.arange(end - n, end) for n, end in zip(sizes, ends, strict=True)]
