"""A block switched mid-run onto another structure against a filter run on that structure from the start.

A switch (a refit or a revision, :mod:`stslam.slam.bodies.decisions`) re-bases the motion state
(``rebase_motion_state``) and replaces the block with its cross-covariances mapped by the Jacobian
(``SlamState.replace_block``), as LandmarkPolicy._rebase does. When the new structure describes the same
path with an affine change of joint variable (a line with another origin and the opposite direction;
a circle about the flipped axis with another zero), the EKF is invariant under that change: predictions,
linearisations and gains map exactly. So the switched filter must equal, frame by frame after the switch,
a filter that held the new structure from its first observation: robot mean and covariance, the
landmark's block, and their cross-covariances. A switch that dropped or mis-mapped cross-covariances, or
re-initialised the block from one observation, fails this by far more than round-off.
"""

from __future__ import annotations

import numpy as np
import pytest

from stslam.articulation.models import PrismaticStructure, get_model
from stslam.articulation.rebase import rebase_motion_state
from stslam.geometry import rotation_z
from stslam.sim.worlds import revolute_structure
from stslam.slam.blocks import ArticulatedBlock
from stslam.slam.core import SlamState

LINE = PrismaticStructure(np.array([2.0, 0.5, 0.6]), np.array([0.6, 0.8, 0.0]), 0.0)
LINE_FLIPPED = PrismaticStructure(LINE.p0 + 0.3 * LINE.direction, -LINE.direction, 0.0)  # q' = 0.3 − q
CIRCLE = revolute_structure([2.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], 0.6)
CIRCLE_FLIPPED = revolute_structure([2.0, 1.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0], 0.6)  # φ' = π/2 − φ
SIGMA_Z = 0.01


def _truth(model_name: str, k: int) -> np.ndarray:
    """The landmark's true position at frame k (q from 0.1 growing 0.02 a frame)."""
    q = 0.1 + 0.02 * k
    structure = LINE if model_name == "prismatic" else CIRCLE
    return get_model(model_name).position(structure, q)


def _run(model_name: str, first, second, switch_at: int | None, n_frames: int = 30):
    """The filter's (x, P) per frame after ``switch_at`` (None: it holds ``first`` throughout), with the
    landmark's block expressed on ``second`` (state order: robot, block)."""
    rng = np.random.default_rng(4)
    state = SlamState(np.zeros(3), np.zeros((3, 3)))
    model = get_model(model_name)
    block = ArticulatedBlock(model, first, 1, 0.01, 0.05)
    pose = np.zeros(3)
    out = []
    for k in range(n_frames):
        if k > 0:
            control = np.array([0.1, 0.04])
            pose = pose + np.array([0.1 * np.cos(pose[2]), 0.1 * np.sin(pose[2]), 0.04])
            state.predict(control, np.diag([1e-4, 1e-4]), 1.0)
        m = _truth(model_name, k)
        z = rotation_z(pose[2]).T @ (m - np.array([pose[0], pose[1], 0.0])) + rng.normal(0.0, SIGMA_Z, 3)
        R = SIGMA_Z ** 2 * np.eye(3)
        if k == 0:
            state.add_landmark(1, block, z, R)
        else:
            state.update_landmark(1, z, R)
        if switch_at is not None and k == switch_at:
            x_new, J = rebase_motion_state(first, second, state.block_mean(1))
            state.replace_block(1, ArticulatedBlock(model, second, 1, 0.01, 0.05), x_new, J, np.zeros((2, 2)))
        if switch_at is None or k >= switch_at:
            out.append((state.x.copy(), state.P.copy()))
    return out


@pytest.mark.parametrize("model_name, first, second", [("prismatic", LINE, LINE_FLIPPED),
                                                      ("revolute", CIRCLE, CIRCLE_FLIPPED)],
                         ids=["line", "circle"])
def test_a_switch_equals_a_filter_on_the_new_structure_from_the_start(model_name, first, second):
    switched = _run(model_name, first, second, switch_at=12)
    scratch = _run(model_name, second, second, switch_at=None)[12:]
    assert len(switched) == len(scratch) == 18
    for (x_a, P_a), (x_b, P_b) in zip(switched, scratch):
        # 18 frames of EKF arithmetic on O(1) numbers: round-off stays far under 1e-9
        np.testing.assert_allclose(x_a, x_b, rtol=0.0, atol=1e-9)
        np.testing.assert_allclose(P_a, P_b, rtol=0.0, atol=1e-10)
    # and the run is not trivial: the block moved and is correlated with the robot
    x, P = switched[-1]
    assert abs(x[3] - switched[0][0][3]) > 0.1
    assert np.abs(P[:3, 3:]).max() > 1e-6
