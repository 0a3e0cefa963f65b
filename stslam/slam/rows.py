"""Joint measurement rows of a SLAM update: k observations of landmarks stacked into one (SPEC 5.3).

Each landmark's predicted observation is a row (z_hat (3,), cols, H_cols (3, c)): H is zero outside the robot's
three columns and the landmark's block's (:meth:`stslam.slam.core.SlamState.predict_observation`).
"""

from __future__ import annotations

import numpy as np

ROBOT = np.arange(3)
ROBOT_SPAN = slice(0, 3)  # ROBOT as a slice (ekf.block_span)


def read_only_row(*arrays) -> tuple:
    """A predicted-observation row (z_hat, cols, H_cols) with its arrays made read-only: one evaluation is shared
    by every caller of one state vector (:meth:`~stslam.slam.core.SlamState.predict_observation`)."""
    for array in arrays:
        array.flags.writeable = False
    return arrays


def stacked_rows(pose, m, dm_dx, idx) -> list:
    """Predicted-observation rows (z_hat, cols, H_cols), read-only, of k landmarks at world positions m (k, 3)
    with ∂m/∂x_b (k, 3, c) (None: I, static points) and state indices idx (k, c), seen from ``pose``
    (:class:`~stslam.robot.sensor.PoseObservation`): H = [∂z/∂pose | ∂z/∂m · ∂m/∂x_b] (SPEC 5.3). Stacked products
    of (3, 3) matrices, which round as the single ones of ``SlamState.predict_observation`` do."""
    k, c = idx.shape
    z_hat, H = pose.observe_many(m, np.empty((k, 3, 3 + c)))  # ∂z/∂pose into H's first three columns
    H[:, :, 3:] = pose.H_m if dm_dx is None else pose.H_m @ dm_dx
    cols = np.empty((k, 3 + c), dtype=int)
    cols[:, :3], cols[:, 3:] = ROBOT, idx
    return [read_only_row(z_hat[n], cols[n], H[n]) for n in range(k)]


def stack_rows(rows, zs) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint (cols, H, y) of predicted-observation ``rows`` (z_hat, cols, H_cols) and observations zs (k, 3).

    cols = robot, then each row's block columns in order; H is block-sparse
    (every row has the robot's three columns and its own block's); y = z − h(x) stacked.
    """
    cols = np.concatenate([ROBOT] + [block_cols[3:] for _, block_cols, _ in rows])
    H = np.zeros((3 * len(rows), cols.size))
    H[:, :3] = np.vstack([H_cols[:, :3] for _, _, H_cols in rows])
    y = np.empty(3 * len(rows))
    offset = 3
    for r, (z_hat, block_cols, H_cols) in enumerate(rows):
        k = block_cols.size - 3
        H[3 * r:3 * r + 3, offset:offset + k] = H_cols[:, 3:]
        y[3 * r:3 * r + 3] = zs[r] - z_hat
        offset += k
    return cols, H, y


def block_diagonal(blocks) -> np.ndarray:
    """The block-diagonal matrix of square (3, 3) blocks, as ``scipy.linalg.block_diag`` builds it."""
    out = np.zeros((3 * len(blocks), 3 * len(blocks)))
    for r, block in enumerate(blocks):
        out[3 * r:3 * r + 3, 3 * r:3 * r + 3] = block
    return out
