"""Prediction groups (stslam/slam/prediction_groups.py): a block appended to a state joins its cached groups
exactly as a rebuild would place it, so the prediction does the same arithmetic either way."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from stslam.slam.blocks import ConstantVelocityPointBlock, StaticPointBlock
from stslam.slam.core import SlamState
from stslam.slam.prediction_groups import PredictionGroups

BLOCKS = (StaticPointBlock(0.0), StaticPointBlock(0.01), StaticPointBlock(0.02),
          ConstantVelocityPointBlock(0.5, 0.1), ConstantVelocityPointBlock(0.3, 0.1))


def _placed(kinds):
    start, placed = 3, []
    for kind in kinds:
        placed.append((start, BLOCKS[kind]))
        start += BLOCKS[kind].size
    return placed


def _assert_same(a: PredictionGroups, b: PredictionGroups):
    assert a.dt == b.dt and a.keys == b.keys and a.spans == b.spans
    assert len(a.blocks) == len(b.blocks)
    for (index_a, F_a, Q_a, fx_a), (index_b, F_b, Q_b, fx_b) in zip(a.blocks, b.blocks, strict=True):
        np.testing.assert_array_equal(index_a, index_b)
        assert index_a.dtype == index_b.dtype and index_a.shape == index_b.shape
        for m_a, m_b in ((F_a, F_b), (Q_a, Q_b)):
            assert (m_a is None) == (m_b is None)
            if m_a is not None:
                assert m_a.tobytes() == m_b.tobytes()
        assert fx_a is None and fx_b is None


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, len(BLOCKS) - 1), min_size=1, max_size=12), st.integers(0, 12),
       st.sampled_from([1.0, 0.1]))
def test_appending_gives_the_groups_a_rebuild_gives(kinds, cached, dt):
    placed = _placed(kinds)
    cached = min(cached, len(placed))
    groups = PredictionGroups.build(placed[:cached], dt)
    for start, block in placed[cached:]:
        groups = groups.appended(start, block)
    _assert_same(groups, PredictionGroups.build(placed, dt))


def test_appending_leaves_the_old_groups_as_they_were():
    placed = _placed([3, 1, 3])
    before = PredictionGroups.build(placed[:2], 1.0)
    snapshot = PredictionGroups.build(placed[:2], 1.0)
    after = before.appended(*placed[2])
    _assert_same(before, snapshot)  # copies of a state share their groups: never changed in place
    assert after.blocks[0][0].shape == (2, 6) and before.blocks[0][0].shape == (1, 6)


def test_a_state_predicts_the_same_with_groups_kept_or_rebuilt():
    rng = np.random.default_rng(0)
    kept = SlamState(np.zeros(3), np.diag([0.01, 0.01, 0.001]))
    for i, kind in enumerate([1, 3, 0, 1, 4, 3]):
        kept.add_landmark(i, BLOCKS[kind], rng.normal(size=3) + [2.0, 0.0, 0.5], 0.01 * np.eye(3))
        kept.predict(np.array([0.3, 0.1]), np.diag([1e-4, 1e-5]), 1.0)  # the groups are cached, then extended
    rebuilt = kept.copy()
    rebuilt._groups = None  # as after a removal: built again from the blocks
    for state in (kept, rebuilt):
        state.predict(np.array([0.3, 0.1]), np.diag([1e-4, 1e-5]), 1.0)
    assert kept.x.tobytes() == rebuilt.x.tobytes() and kept.P.tobytes() == rebuilt.P.tobytes()
