"""A state's blocks grouped by their transition, for one prediction step (SPEC 6; ``ekf.predict_blocks``).

Blocks whose transition over δt is the same (F and Q equal to the bit) are predicted as one group: one
batched product instead of one per block. A state keeps its groups until its blocks change; a block
appended at the end of the state joins them without a rebuild (:meth:`PredictionGroups.appended`),
giving the same groups, in the same order, as a rebuild would.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stslam.kalman import ekf

__all__ = ["PredictionGroups"]


@dataclass(frozen=True)
class PredictionGroups:
    """Per distinct transition: ``blocks`` (index (b, k), F, Q, None) as ``ekf.predict_blocks`` takes them,
    ``spans`` each index's ``ekf.block_span`` and ``keys`` its (size, F bytes, Q bytes); all over ``dt``.
    Immutable: copies of a state share it."""

    dt: float
    blocks: tuple = ()
    spans: tuple = ()
    keys: tuple = ()

    @classmethod
    def build(cls, placed, dt: float) -> PredictionGroups:
        """The groups of ``placed``, (start, block) pairs in state order; blocks without F and Q are left out."""
        groups: dict = {}
        for start, block in placed:
            grouped = _transition_key(block, dt)
            if grouped is not None:
                key, F, Q = grouped
                groups.setdefault(key, (F, Q, []))[2].append(np.arange(start, start + block.size))
        blocks = tuple((np.array(index), F, Q, None) for F, Q, index in groups.values())
        return cls(dt, blocks, tuple(ekf.block_span(index) for index, _, _, _ in blocks), tuple(groups))

    def appended(self, start: int, block) -> PredictionGroups:
        """These groups with ``block`` appended at ``start``, the end of the state: the last of its group, or
        the first of a new last group, as :meth:`build` would place it. New arrays; this one is unchanged."""
        grouped = _transition_key(block, self.dt)
        if grouped is None:
            return self
        key, F, Q = grouped
        index = np.arange(start, start + block.size)
        if key not in self.keys:
            return PredictionGroups(self.dt, (*self.blocks, (index[None, :], F, Q, None)),
                                    (*self.spans, ekf.block_span(index)), (*self.keys, key))
        g = self.keys.index(key)
        stacked = np.vstack((self.blocks[g][0], index))
        blocks = (*self.blocks[:g], (stacked, *self.blocks[g][1:]), *self.blocks[g + 1:])
        spans = (*self.spans[:g], ekf.block_span(stacked), *self.spans[g + 1:])
        return PredictionGroups(self.dt, blocks, spans, self.keys)


def _transition_key(block, dt: float):
    """(key, F, Q) of a block's transition over ``dt``, or None for a block that stays as it is."""
    F, Q = block.transition(dt)  # moving blocks compute theirs once per δt (MotionModel)
    if F is None and Q is None:
        return None
    return (block.size, None if F is None else F.tobytes(), None if Q is None else Q.tobytes()), F, Q
