"""A smoother takes a flagged point's observations since its onset out of the graph (stslam.graph.reread.withdraw)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("gtsam")

from stslam.graph.state import GraphState, Isam2Settings  # noqa: E402
from stslam.robot.motion import move  # noqa: E402
from stslam.robot.sensor import observe  # noqa: E402
from stslam.slam.blocks import StaticPointBlock  # noqa: E402

R = 0.02**2 * np.eye(3)
POINTS = {1: np.array([2.0, 1.0, 0.2]), 2: np.array([2.5, -1.0, 0.3]), 3: np.array([3.0, 0.5, 0.8])}
N_FRAMES, ONSET = 10, 6  # point 3 slides from frame ONSET on


def _run(skip_from=None, withdraw_at=None, regate_probability=None):
    """Odometry with noise, three points; point 3's observations from frame ``skip_from`` left out, or used
    until frame ``withdraw_at``, where those from ONSET on are withdrawn, and held out after it (as A-SLAM's
    onset test holds a flagged point)."""
    rng = np.random.default_rng(5)
    state = GraphState(np.zeros(3), np.zeros((3, 3)), motion_order=1,
                       settings=Isam2Settings(floor_sigma=1e-7, regate_probability=regate_probability))
    truth = np.zeros(3)
    for k in range(N_FRAMES):
        if k:
            truth = move(truth, np.array([0.3, 0.05]), 1.0)
            state.predict(np.array([0.3, 0.05]) + rng.normal(0, [0.02, 0.005]), np.diag([0.02**2, 0.005**2]), 1.0)
        seen = {i: m + (np.array([0.04 * (k - ONSET + 1), 0.0, 0.0]) if i == 3 and k >= ONSET else 0.0)
                for i, m in POINTS.items()}
        zs = {i: observe(truth, m) + rng.normal(0, 0.02, 3) for i, m in seen.items()}
        if k == 0:
            for i, z in zs.items():
                state.add_landmark(i, StaticPointBlock(), z, R)
            continue
        held = (skip_from is not None and k >= skip_from) or (withdraw_at is not None and k > withdraw_at)
        ids = [i for i in POINTS if i != 3 or not held]
        state.update_landmarks(ids, np.array([zs[i] for i in ids]), R)
        if withdraw_at == k:
            assert state.withdraw(3, ONSET) == k - ONSET + 1
    return state.smoothed()[0]


def test_withdrawn_observations_leave_the_graph_as_if_never_used():
    never = _run(skip_from=ONSET)
    withdrawn = _run(withdraw_at=ONSET + 2)
    used = _run()
    # the sliding point pulled the poses by 6 cm; with its observations since the onset withdrawn they are
    # where they are without them. Both graphs hold the same factors, but iSAM2 relinearises a variable only
    # past its thresholds (5 cm, 0.01 rad), so their linearisation points differ: 6e-5 m measured, bound 2e-4
    assert np.abs(used - never).max() > 0.03
    np.testing.assert_allclose(withdrawn, never, atol=2e-4)


def test_a_point_keeps_its_first_observation():
    rng_state = GraphState(np.zeros(3), np.zeros((3, 3)), motion_order=1, settings=Isam2Settings(floor_sigma=1e-7))
    rng_state.add_landmark(1, StaticPointBlock(), observe(np.zeros(3), POINTS[1]), R)
    assert rng_state.withdraw(1, 0) == 0  # its one observation factor stays: its variable keeps a factor
    assert rng_state.withdraw(99, 0) == 0  # not in the state


def test_a_withdrawal_forgets_the_gate_marginals_of_its_factors_keys():
    """The final re-test bounds a marginal by the one at its gate, which holds only while factors are added:
    the keys of withdrawn factors (the poses of frames since the onset) lose theirs (stslam.graph.regate)."""
    from stslam.graph.state import pose_key

    state = GraphState(np.zeros(3), np.zeros((3, 3)), motion_order=1, settings=Isam2Settings(floor_sigma=1e-7))
    truth = np.zeros(3)
    for i, m in POINTS.items():
        state.add_landmark(i, StaticPointBlock(), observe(truth, m), R)
    for _ in range(4):
        truth = move(truth, np.array([0.3, 0.05]), 1.0)
        state.predict(np.array([0.3, 0.05]), np.diag([0.02**2, 0.005**2]), 1.0)
        state.update_landmarks(list(POINTS), np.array([observe(truth, m) for m in POINTS.values()]), R, 1e9)
    assert all(pose_key(k) in state._gate_marginals for k in range(1, 5))  # every frame's gate asked its pose
    assert state.withdraw(3, 3) == 2
    assert [pose_key(k) in state._gate_marginals for k in range(1, 5)] == [True, True, False, False]
