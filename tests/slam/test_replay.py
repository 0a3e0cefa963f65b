"""Rolling the EKF back to a point's onset and replaying without it (stslam.slam.replay)."""

from __future__ import annotations

import numpy as np

from stslam.slam.blocks import StaticPointBlock
from stslam.slam.core import SlamState
from stslam.slam.replay import ReplayHistory

N_FRAMES = 12
ONSET = 6  # landmark 2 begins to move at this frame
BLOCK = StaticPointBlock(0.0)


def _sequence(seed=3):
    """Controls and observations of four points, point 2 sliding away from frame ONSET on."""
    rng = np.random.default_rng(seed)
    controls = np.tile([0.2, 0.05], (N_FRAMES - 1, 1))
    control_covs = np.repeat(np.diag([1e-3, 1e-4])[None], N_FRAMES - 1, axis=0)
    dts = np.ones(N_FRAMES - 1)
    points = np.array([[2.0, 1.0, 0.5], [3.0, -1.0, 0.2], [2.5, 0.0, 1.0], [4.0, 2.0, 0.0]])
    zs = []
    pose = np.zeros(3)
    for k in range(N_FRAMES):
        if k:
            v, w = controls[k - 1]
            pose = pose + [v * np.cos(pose[2]), v * np.sin(pose[2]), w]
        moved = points.copy()
        moved[2, 0] += 0.03 * max(0, k - ONSET + 1)
        c, s = np.cos(pose[2]), np.sin(pose[2])
        rel = moved - [pose[0], pose[1], 0.0]
        zs.append(np.column_stack([c * rel[:, 0] + s * rel[:, 1], -s * rel[:, 0] + c * rel[:, 1], rel[:, 2]])
                  + rng.normal(0, 0.01, (4, 3)))
    return controls, control_covs, dts, np.array(zs)


def _run(skip_from: dict, history: ReplayHistory | None = None, restart_at: int | None = None):
    """The EKF over the sequence, landmark i's observations left out from frame skip_from[i] on; with
    ``restart_at``, landmark 0 is re-placed from that frame's observation after its update."""
    controls, control_covs, dts, zs = _sequence()
    R = np.repeat((0.01 ** 2 * np.eye(3))[None], 4, axis=0)
    state = SlamState(np.zeros(3), np.zeros((3, 3)))
    for k in range(N_FRAMES):
        if k:
            state.predict(controls[k - 1], control_covs[k - 1], float(dts[k - 1]))
        if history is not None:
            history.begin(k, state)
        ids = [i for i in range(4) if i in state and k < skip_from.get(i, N_FRAMES)]
        if ids:
            state.update_landmarks(ids, zs[k][ids], R[ids])
            if history is not None:
                history.record("joint", ids, zs[k][ids], R[ids])
        if k == restart_at:  # a change of the state's layout, journaled (stslam.slam.journal)
            state.remove_landmark(0)
            state.add_landmark(0, BLOCK, zs[k][0], R[0])
        for i in range(4):
            if i not in state:
                state.add_landmark(i, BLOCK, zs[k][i], R[i])  # journaled
    return state, (controls, control_covs, dts)


def test_a_replay_equals_the_filter_that_never_used_the_point_since_its_onset():
    controls, control_covs, dts, _ = _sequence()
    history = ReplayHistory(30, controls, control_covs, dts)
    state, _ = _run({}, history)
    assert history.replay(state, [2], ONSET)
    reference, _ = _run({2: ONSET})
    # the same arithmetic in the same order: equal to rounding (1e-12 m, m² on values of order 1)
    np.testing.assert_allclose(state.x, reference.x, atol=1e-12)
    np.testing.assert_allclose(state.P, reference.P, atol=1e-12)
    assert history.replays == 1 and history.replayed_frames == N_FRAMES - ONSET
    # and the replay moved the robot: the sliding point had pulled it (else the test shows nothing)
    unreplayed, _ = _run({})
    assert np.linalg.norm(unreplayed.x[:2] - state.x[:2]) > 1e-4


def test_a_replay_reaches_back_no_further_than_the_history():
    controls, control_covs, dts, _ = _sequence()
    history = ReplayHistory(3, controls, control_covs, dts)
    state, _ = _run({}, history)
    # its rise lies before the three frames kept: the replay starts at the oldest
    assert history.replay(state, [2], 0)
    reference, _ = _run({2: N_FRAMES - 3})
    np.testing.assert_allclose(state.x, reference.x, atol=1e-12)


def test_a_replay_redoes_the_journaled_changes_of_the_frames_it_replays():
    controls, control_covs, dts, _ = _sequence()
    history = ReplayHistory(30, controls, control_covs, dts)
    state, _ = _run({}, history, restart_at=ONSET + 2)
    assert history.replay(state, [2], ONSET)
    reference, _ = _run({2: ONSET}, restart_at=ONSET + 2)
    assert state.landmark_ids == reference.landmark_ids == [1, 2, 3, 0]  # the restart moved 0 to the end
    np.testing.assert_allclose(state.x, reference.x, atol=1e-12)
    np.testing.assert_allclose(state.P, reference.P, atol=1e-12)
    assert state.journal is history  # the replayed state still reports to the history


def test_nothing_to_replay_when_the_point_was_not_used_and_a_change_not_journaled_ends_the_history():
    controls, control_covs, dts, _ = _sequence()
    history = ReplayHistory(30, controls, control_covs, dts)
    state, _ = _run({2: ONSET}, history)
    before = state.x
    assert not history.replay(state, [2], ONSET) and state.x is before
    history.watch(state)
    state.remove_landmark(3)  # journaled: expected
    history.check(state)
    assert len(history.entries) == N_FRAMES and history.entries[-1].ops[-1][:2] == ("call", "remove_landmark")
    history.watch(state)
    state.P = state.P + 1e-9 * np.eye(state.P.shape[0])  # a change the history cannot redo
    history.check(state)
    assert len(history.entries) == 0
