"""The one SLAM frame loop (run_slam with a policy) and the trial copy of a SlamState (SPEC 5.1, 6)."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.robot.motion import move
from stslam.robot.sensor import observe
from stslam.slam.blocks import ConstantVelocityPointBlock, StaticPointBlock
from stslam.slam.core import SlamState
from stslam.slam.inputs import SlamInputs
from stslam.slam.loop import BlockPolicy, FilterTrack, run_slam

SIGMA_M = 0.04
R = SIGMA_M**2 * np.eye(3)
LANDMARKS = np.array([[2.0, 0.5, 0.3], [1.5, -1.0, 0.1], [3.0, 1.2, 0.6]])
# Per frame the landmarks seen, in the order the sensor reports them: new ones appear
# among known ones, and frame 3 sees landmark 0 again after a gap.
SEEN = ([0, 1], [1, 2], [2, 1], [0, 2, 1])


def _tiny_inputs(seed=0, moved=None):
    """Four frames of a robot driving a gentle arc past three landmarks; ``moved`` shifts a landmark in frame 3."""
    rng = np.random.default_rng(seed)
    controls = np.array([[0.3, 0.1], [0.3, 0.05], [0.25, -0.1]])
    dts = np.array([1.0, 0.5, 1.0])
    poses = [np.array([0.1, -0.2, 0.05])]
    for u, dt in zip(controls, dts, strict=True):
        poses.append(move(poses[-1], u, dt))
    ids, zs = [], []
    for k, seen in enumerate(SEEN):
        points = LANDMARKS.copy()
        if moved is not None and k == 3:
            points[moved] += [0.0, 0.5, 0.0]
        ids.append(np.array(seen))
        zs.append(np.array([observe(poses[k], points[i]) for i in seen]) + rng.normal(0, SIGMA_M, (len(seen), 3)))
    return SlamInputs(poses[0], controls + rng.normal(0, 0.01, controls.shape),
                      np.array([np.diag([1e-4, 4e-4])] * 3), dts, tuple(ids), tuple(zs),
                      tuple(np.broadcast_to(R, (len(seen), 3, 3)) for seen in SEEN))


def _by_hand(inputs, block, max_nis=None, motion_order=2, update_iterations=1):
    """The baselines' frame steps written out for :data:`SEEN`: predict, joint update of known ones, add new ones."""
    state = SlamState(inputs.initial_pose_xytheta, np.zeros((3, 3)), motion_order, update_iterations)
    zs, Rs = inputs.observations, inputs.observation_covs
    poses, covs, rejected = [], [], 0

    def predict(k):
        state.predict(inputs.controls_vw[k - 1], inputs.control_covs[k - 1], float(inputs.dts_s[k - 1]))

    def update(k, rows):
        ids = [SEEN[k][j] for j in rows]
        accepted, _ = state.update_landmarks(ids, zs[k][rows], Rs[k][rows], max_nis)
        return int(np.count_nonzero(~accepted))

    def record():
        poses.append(state.pose)
        covs.append(state.pose_cov)

    state.add_landmark(0, block, zs[0][0], Rs[0][0])  # frame 0: both new
    state.add_landmark(1, block, zs[0][1], Rs[0][1])
    record()
    predict(1)  # frame 1: landmark 1 known, 2 new
    rejected += update(1, [0])
    state.add_landmark(2, block, zs[1][1], Rs[1][1])
    record()
    predict(2)  # frame 2: both known
    rejected += update(2, [0, 1])
    record()
    predict(3)  # frame 3: all known
    rejected += update(3, [0, 1, 2])
    record()
    return np.array(poses), np.array(covs), rejected


@pytest.mark.parametrize("block", [StaticPointBlock(0.01), ConstantVelocityPointBlock(0.01, 0.1)])
@pytest.mark.parametrize("motion_order, update_iterations", [(2, 1), (1, 3)])
def test_block_policy_is_the_hand_written_frame_sequence(block, motion_order, update_iterations):
    inputs = _tiny_inputs()
    poses, covs, rejected = _by_hand(inputs, block, None, motion_order, update_iterations)
    track = run_slam(inputs, BlockPolicy(lambda i: block), motion_order, update_iterations)
    assert isinstance(track, FilterTrack)
    # The same operations in the same order: exactly equal, not merely close.
    np.testing.assert_array_equal(track.poses_xytheta, poses)
    np.testing.assert_array_equal(track.pose_covs, covs)
    assert track.n_rejected == rejected == 0


def test_gated_block_policy_counts_the_rejections_of_the_hand_written_gate():
    # Landmark 0 jumps 0.5 m (12σ) in frame 3: the χ²₃ 99% gate (11.34) rejects it, and only it.
    inputs = _tiny_inputs(moved=0)
    block = StaticPointBlock(0.0)
    poses, covs, rejected = _by_hand(inputs, block, max_nis=11.34)
    track = run_slam(inputs, BlockPolicy(lambda i: block, 11.34))
    np.testing.assert_array_equal(track.poses_xytheta, poses)
    np.testing.assert_array_equal(track.pose_covs, covs)
    assert track.n_rejected == rejected == 1
    ungated = run_slam(inputs, BlockPolicy(lambda i: block))
    assert ungated.n_rejected == 0 and not np.array_equal(ungated.poses_xytheta[3], track.poses_xytheta[3])


class _Recording:
    """A BlockPolicy whose hooks are logged; it leaves observation 0 of every frame ≥ 1 out of the update."""

    def __init__(self, block, log):
        self.inner, self.log = BlockPolicy(lambda i: block), log

    def before_update(self, state, frame):
        self.log.append(("before_update", frame.k))
        return {0} if frame.k > 0 else set()

    def update(self, state, frame, skip):
        self.log.append(("update", frame.k, tuple(sorted(skip))))
        outcome = self.inner.update(state, frame, skip)
        return {j: False for j in outcome} if frame.k == 2 else outcome  # frame 2: reported rejected

    def after_update(self, state, frame, outcome):
        self.log.append(("after_update", frame.k, tuple(sorted(outcome))))

    def add_landmark(self, state, landmark_id, z_robot, R):
        self.log.append(("add_landmark", landmark_id))
        self.inner.add_landmark(state, landmark_id, z_robot, R)

    def after_frame(self, state, frame):
        self.log.append(("after_frame", frame.k, state.x.size))

    def track(self, poses_xytheta, pose_covs, n_rejected):
        return self.inner.track(poses_xytheta, pose_covs, n_rejected)


def test_the_loop_calls_the_hooks_in_order_and_counts_what_the_policy_rejects():
    log = []
    track = run_slam(_tiny_inputs(), _Recording(StaticPointBlock(0.01), log),
                     observer=lambda k, state: log.append(("observer", k)))
    assert log == [
        ("before_update", 0), ("update", 0, ()), ("after_update", 0, ()),
        ("add_landmark", 0), ("add_landmark", 1), ("after_frame", 0, 9), ("observer", 0),
        # Frame 1 sees [1, 2]: observation 0 (landmark 1) is left out, landmark 2 is new.
        ("before_update", 1), ("update", 1, (0,)), ("after_update", 1, ()),
        ("add_landmark", 2), ("after_frame", 1, 12), ("observer", 1),
        # Frame 2 sees [2, 1]: observation 1 updates, and the policy reports it rejected.
        ("before_update", 2), ("update", 2, (0,)), ("after_update", 2, (1,)),
        ("after_frame", 2, 12), ("observer", 2),
        ("before_update", 3), ("update", 3, (0,)), ("after_update", 3, (1, 2)),
        ("after_frame", 3, 12), ("observer", 3),
    ]
    assert track.n_rejected == 1


class _RecordingIds(_Recording):
    """_Recording whose after_frame logs the landmark ids it is shown."""

    def after_frame(self, state, frame):
        self.log.append(("after_frame", frame.k, tuple(frame.ids)))


def test_observing_every_second_frame_runs_the_update_hooks_on_even_frames_only():
    log = []
    track = run_slam(_tiny_inputs(), _RecordingIds(StaticPointBlock(0.01), log), observe_every=2)
    assert log == [
        ("before_update", 0), ("update", 0, ()), ("after_update", 0, ()),
        ("add_landmark", 0), ("add_landmark", 1), ("after_frame", 0, (0, 1)),
        # Frame 1 sees [1, 2]: only odometry reaches the state; the policy is shown landmark 1, which it
        # knows, and not landmark 2, first seen here and added at the next observing frame that sees it.
        ("after_frame", 1, (1,)),
        ("before_update", 2), ("update", 2, (0,)), ("after_update", 2, (1,)),
        ("add_landmark", 2), ("after_frame", 2, (2, 1)),
        ("after_frame", 3, (0, 2, 1)),
    ]
    assert track.n_rejected == 1  # the rejection the policy reported at frame 2; frames 1 and 3 count none


def test_observing_every_second_frame_is_the_run_whose_odd_frames_saw_nothing():
    inputs = _tiny_inputs(seed=4)
    blind = SlamInputs(inputs.initial_pose_xytheta, inputs.controls_vw, inputs.control_covs, inputs.dts_s,
                       *(tuple(a if k % 2 == 0 else a[:0] for k, a in enumerate(field))
                         for field in (inputs.observation_ids, inputs.observations, inputs.observation_covs)))
    policy = lambda: BlockPolicy(lambda i: StaticPointBlock(0.01), 7.81)  # noqa: E731
    every_other = run_slam(inputs, policy(), observe_every=2)
    expected = run_slam(blind, policy())
    np.testing.assert_array_equal(every_other.poses_xytheta, expected.poses_xytheta)
    np.testing.assert_array_equal(every_other.pose_covs, expected.pose_covs)
    every = run_slam(inputs, policy())
    assert not np.allclose(every.poses_xytheta[1:], every_other.poses_xytheta[1:])


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_observe_every_must_be_a_positive_integer(bad):
    with pytest.raises(ValueError, match=r"^observe_every: expected an integer ≥ 1"):
        run_slam(_tiny_inputs(), BlockPolicy(lambda i: StaticPointBlock()), observe_every=bad)
