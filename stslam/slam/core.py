"""The SLAM state every filter shares: robot pose plus landmark blocks (SPEC 6).

State x = [x, y, θ | block_1 | block_2 | …] with covariance P (world frame; m, rad and the blocks'
own units). The robot always occupies indices 0–2; each landmark id owns a contiguous block whose
meaning its block object defines (:mod:`stslam.slam.blocks`). All Kalman arithmetic goes through
:mod:`stslam.kalman.ekf`; this class only assembles Jacobians and keeps the index.

Per step the work is O(n²) in the state size: the prediction multiplies only the robot's and moving
blocks' rows and columns (``ekf.predict_blocks``), and each update touches only the robot's and the
observed block's columns of H (``ekf.update_sparse``).

Hooks for A-SLAM: :meth:`predict_observation`, gated :meth:`update_landmark`, :meth:`replace_block` (a block
to another kind, with a Jacobian), :meth:`remove_landmark` (journaled for a replay: :mod:`stslam.slam.journal`);
blocks' ``frozen`` entries are consider parameters.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from stslam.kalman import ekf
from stslam.robot.motion import motion_jacobians, move, second_order_motion_noise
from stslam.robot.sensor import PoseObservation, point_from_observation
from stslam.slam.blocks import StaticPointBlock, stack_key, stacked_positions
from stslam.slam.journal import journaled
from stslam.slam.prediction_groups import PredictionGroups
from stslam.slam.rows import ROBOT, ROBOT_SPAN, block_diagonal, read_only_row, stack_rows, stacked_rows


class LandmarkTable:
    """Landmark queries shared by the estimators' states.

    A subclass's ``_landmark_table()`` maps each landmark id to a tuple whose last item is its block.
    """

    def _landmark_table(self) -> dict:
        raise NotImplementedError

    def __contains__(self, landmark_id) -> bool:
        return landmark_id in self._landmark_table()

    @property
    def landmark_ids(self) -> list:
        """Ids of the landmarks in the state, in the order they were added."""
        return list(self._landmark_table())

    def block(self, landmark_id):
        """The landmark's block."""
        return self._landmark_table()[landmark_id][-1]

    def landmark_point(self, landmark_id) -> np.ndarray:
        """World position m (3,) of a landmark: ``landmark_position`` without the covariance."""
        return self.landmark_position(landmark_id)[0]


class SlamState(LandmarkTable):
    """Mean and covariance of robot + landmark blocks, with the block index.

    Parameters
    ----------
    pose_xytheta : array_like, shape (3,)
        Initial robot pose (x m, y m, θ rad), world frame.
    pose_cov : array_like, shape (3, 3)
        Its covariance (zero for a known start).
    motion_order : {1, 2}
        How the control noise enters the robot's prediction: 1, V S Vᵀ (the textbook EKF); 2
        (default), plus the second-order term Q₂ of :func:`stslam.robot.motion.second_order_motion_noise`.
    update_iterations : int
        1 (default): the EKF update. k > 1: the iterated EKF, whose update is relinearised k − 1 times
        at its own result (Gauss–Newton on the update's MAP cost; Bell & Cathey 1993). Gates, NIS and
        likelihoods stay those of the first linearisation, at the prediction.
    """

    def __init__(self, pose_xytheta, pose_cov, motion_order: int = 2, update_iterations: int = 1):
        if motion_order not in (1, 2):
            raise ValueError(f"motion_order: expected 1 or 2, got {motion_order!r}")
        if isinstance(update_iterations, bool) or not isinstance(update_iterations, int) or update_iterations < 1:
            raise ValueError(f"update_iterations: expected an integer ≥ 1, got {update_iterations!r}")
        self.motion_order = motion_order
        self.update_iterations = update_iterations
        self.x = np.asarray(pose_xytheta, dtype=float).copy()
        self.P = np.asarray(pose_cov, dtype=float).copy()
        self._blocks: dict = {}  # landmark id -> (start index, block)
        self._groups: PredictionGroups | None = None  # kept until blocks change (appending extends it)
        self._frozen: np.ndarray | None = None  # consider parameters' indices (:meth:`frozen`), cached likewise
        self._rows: dict = {}  # landmark id -> predicted observation at the state vector self._rows_x
        self._rows_x: np.ndarray | None = None
        self._pose_terms: PoseObservation | None = None  # at self._rows_x

    @classmethod
    def from_blocks(cls, x, P, blocks, motion_order: int = 2, update_iterations: int = 1) -> SlamState:
        """A state with mean x and covariance P laid out as robot, then ``blocks`` ((id, block), …) in order."""
        state = cls(np.asarray(x, dtype=float)[:3], np.asarray(P, dtype=float)[:3, :3], motion_order,
                    update_iterations)
        state.x, state.P = np.asarray(x, dtype=float).copy(), np.asarray(P, dtype=float).copy()
        start = 3
        for landmark_id, block in blocks:
            state._blocks[landmark_id] = (start, block)
            start += block.size
        if start != state.x.size or state.P.shape != (start, start):
            raise ValueError(f"from_blocks: blocks need a state of size {start}, got x {state.x.shape}, P {state.P.shape}")
        return state

    def copy(self) -> SlamState:
        """An independent state (no journal): x, P and the block index copied; blocks (and their motion
        models' cached transitions) are immutable and cached prediction groups replaced, never changed: shared."""
        other = SlamState.__new__(SlamState)
        other.motion_order, other.update_iterations = self.motion_order, self.update_iterations
        other.x, other.P = self.x.copy(order="K"), self.P.copy(order="K")  # same memory layout, same arithmetic
        other._blocks = dict(self._blocks)
        other._groups = self._groups  # immutable: shared
        other._frozen = self._frozen
        other._rows, other._rows_x, other._pose_terms = {}, None, None
        return other

    # ------------------------------------------------------------------ queries
    @property
    def pose(self) -> np.ndarray:
        """Robot pose estimate (3,)."""
        return self.x[:3].copy()

    @property
    def pose_cov(self) -> np.ndarray:
        """Robot pose covariance (3, 3), world frame."""
        return self.P[:3, :3].copy()

    def _landmark_table(self) -> dict:
        return self._blocks

    def indices(self, landmark_id) -> np.ndarray:
        """State indices (k,) of a landmark's block."""
        start, block = self._blocks[landmark_id]
        return np.arange(start, start + block.size)

    def block_mean(self, landmark_id) -> np.ndarray:
        """The landmark's block state x_b (k,) (a copy)."""
        return self.x[self.indices(landmark_id)].copy()

    def landmark_position(self, landmark_id) -> tuple[np.ndarray, np.ndarray]:
        """World position m (3,) of a landmark and its covariance (3, 3) by first-order propagation."""
        idx = self.indices(landmark_id)
        m, dm_dx = self.block(landmark_id).position(self.x[idx])
        return np.asarray(m, dtype=float), dm_dx @ self.P[np.ix_(idx, idx)] @ dm_dx.T

    def landmark_positions(self, landmark_ids) -> list:
        """:meth:`landmark_position` of each landmark; the static points' gathered together (m = x_b and
        its block of P: SPEC 6.1's ∂m/∂x_b = I, the same numbers)."""
        static = [i for i in landmark_ids if type(self.block(i)) is StaticPointBlock]
        idx = np.array([self.indices(i) for i in static], dtype=int).reshape(-1, 3)
        gathered = dict(zip(static, zip(self.x[idx], self.P[idx[:, :, None], idx[:, None, :]])))
        return [gathered[i] if i in gathered else self.landmark_position(i) for i in landmark_ids]

    # -------------------------------------------------------------- prediction
    def predict(self, control_vw, control_cov, dt: float) -> None:
        """Robot by SPEC 5.1 (F = G, Q = V S Vᵀ [+ Q₂]) and every block by its transition.

        ``control_cov`` is S (2, 2), the covariance of the control (v, ω); Q₂
        (``motion_order`` 2) is the control noise's second-order term
        (:func:`stslam.robot.motion.second_order_motion_noise`). Blocks with the same
        transition are predicted as one group.
        """
        G, V = motion_jacobians(self.x[:3], control_vw, dt)
        Q = V @ control_cov @ V.T  # SPEC 5.1
        if self.motion_order == 2:
            Q = Q + second_order_motion_noise(self.x[:3], control_vw, control_cov, dt)  # Bar-Shalom et al. 2001, §10.3
        robot = (ROBOT, G, Q, move(self.x[:3], control_vw, dt))
        groups, spans = self._prediction_groups(dt)
        self.x, self.P = ekf.predict_blocks(self.x, self.P, [robot, *groups], [ROBOT_SPAN, *spans])

    def _prediction_groups(self, dt: float) -> tuple[tuple, tuple]:
        """(index (b, k), F, Q, None) per distinct block transition, and each index's ``ekf.block_span``
        (:class:`~stslam.slam.prediction_groups.PredictionGroups`); kept until blocks change."""
        if self._groups is None or self._groups.dt != dt:
            self._groups = PredictionGroups.build(self._blocks.values(), dt)
        return self._groups.blocks, self._groups.spans

    def frozen(self) -> np.ndarray:
        """State indices of consider parameters (a block's ``frozen`` entries): the updates leave them as they are."""
        if self._frozen is None:
            self._frozen = np.array([start + j for start, block in self._blocks.values()
                                     for j in getattr(block, "frozen", ())], dtype=int)
        return self._frozen

    # -------------------------------------------------------------- observation
    def predict_observation(self, landmark_id, x=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted z (3,), the state columns where H is non-zero, and those columns of H.

        h(x) = R(θ)ᵀ(m(x_b) − [x, y, 0]ᵀ);  H = [∂z/∂pose | ∂z/∂m · ∂m/∂x_b] (SPEC 5.3),
        at the current state or at ``x`` (a state vector of the same layout).
        """
        if x is None:
            rows = self._current_rows()
            row = rows.get(landmark_id)
            if row is None:
                row = rows[landmark_id] = self._predict_observation(landmark_id, self.x, self._pose_terms)
            return row
        return self._predict_observation(landmark_id, x, PoseObservation(x[:3]))

    def _current_rows(self) -> dict:
        """Predicted observations kept per landmark until x changes: it is never changed in place, only replaced
        (prediction, update, blocks changed), so the gate and the update of one frame share one evaluation."""
        if self._rows_x is not self.x:
            self._rows, self._rows_x, self._pose_terms = {}, self.x, PoseObservation(self.x[:3])
        return self._rows

    def predict_observations(self, landmark_ids) -> list:
        """:meth:`predict_observation` of each landmark at the current state; those whose blocks share a
        :func:`~stslam.slam.blocks.stack_key` together (the same numbers), then kept as the single ones are."""
        rows, groups = self._current_rows(), {}
        for i in landmark_ids:
            if i not in rows and (key := stack_key(self.block(i))) is not None:
                groups.setdefault(key, {})[i] = None  # (in order, once each)
        for ids in groups.values():
            if len(ids) > 1:
                ids = list(ids)
                idx = np.array([self.indices(i) for i in ids], dtype=int)
                m, dm_dx = stacked_positions([self.block(i) for i in ids], self.x[idx])
                for i, row in zip(ids, stacked_rows(self._pose_terms, m, dm_dx, idx), strict=True):
                    rows[i] = row
        return [self.predict_observation(i) for i in landmark_ids]

    def _predict_observation(self, landmark_id, x, pose) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        idx = self.indices(landmark_id)
        m, dm_dx = self.block(landmark_id).position(x[idx])
        z_hat, H_pose = pose.observe(m)
        return read_only_row(z_hat, np.concatenate([ROBOT, idx]), np.concatenate((H_pose, pose.H_m @ dm_dx), axis=1))

    def update_landmark(self, landmark_id, z_robot, R, max_nis: float | None = None) -> ekf.Update:
        """EKF update with one observation z (3,) of a landmark in the state (gated if ``max_nis``)."""
        z = np.asarray(z_robot, dtype=float).reshape(1, 3)
        z_hat, cols, H_cols = self.predict_observation(landmark_id)
        result = ekf.update_sparse(self.x, self.P, z[0] - z_hat, cols, H_cols, R, max_nis, self.frozen())
        if result.accepted:
            result = self._iterate(result, [landmark_id], z, R, cols)
            self.x, self.P = result.x, result.P
        return result

    def update_each(self, landmark_ids, zs_robot, Rs, max_nis: float | None = None) -> np.ndarray:
        """Observations z (k, 3) with noises Rs (k, 3, 3) one after another, each gated against the state
        its predecessor left (:meth:`update_landmark`); accepted (k,) bool."""
        return np.array([bool(self.update_landmark(i, z, R, max_nis).accepted)
                         for i, z, R in zip(landmark_ids, zs_robot, Rs, strict=True)], dtype=bool)

    def _iterate(self, first: ekf.Update, landmark_ids, zs, R, cols) -> ekf.Update:
        """Relinearise an accepted update ``update_iterations − 1`` times (iterated EKF).

        xᵢ₊₁ = x⁻ + Kᵢ (z − h(xᵢ) − Hᵢ (x⁻ − xᵢ)) with Hᵢ, Kᵢ at xᵢ, from the same
        prior x⁻, P⁻ (the state before the update); P is the last iteration's.
        Returns ``first`` with the final x and P.
        """
        if self.update_iterations == 1:
            return first
        result = first
        for _ in range(self.update_iterations - 1):
            x_lin = result.x
            rows = [self.predict_observation(i, x_lin) for i in landmark_ids]
            cols_i, H, y = stack_rows(rows, zs)
            assert np.array_equal(cols_i, cols)  # blocks do not move during an update
            y = y - H @ (self.x[cols] - x_lin[cols])
            result = ekf.update_sparse(self.x, self.P, y, cols, H, R, frozen=self.frozen())
        return replace(first, x=result.x, P=result.P)

    def update_landmarks(self, landmark_ids, zs_robot, R, max_nis=None):
        """One joint EKF update with the observations z (k, 3) of landmarks already in the state.

        With ``max_nis`` (one bound for all, or a sequence of k bounds with None
        for "no gate"), each observation is first gated on its own NIS
        yᵢᵀSᵢ⁻¹yᵢ (Sᵢ its marginal innovation covariance); the accepted ones
        are then used together (H stacked, R block-diagonal). ``R`` is one
        covariance (3, 3) for all or one per observation (k, 3, 3) (m², robot frame).

        Returns
        -------
        accepted : numpy.ndarray of bool, shape (k,)
        result : ekf.Update or None
            The joint update (None when nothing was accepted).
        """
        rows = self.predict_observations(landmark_ids)
        zs = np.asarray(zs_robot, dtype=float).reshape(len(rows), 3)
        R = np.asarray(R, dtype=float)
        Rs = R if R.ndim == 3 else None  # per-observation covariances, or one for all
        accepted = np.ones(len(rows), dtype=bool)
        bounds = max_nis if isinstance(max_nis, (list, tuple, np.ndarray)) else [max_nis] * len(rows)
        gated = [j for j in range(len(rows)) if bounds[j] is not None]
        if gated:
            nis = self._nis([rows[j] for j in gated], zs[gated], R if Rs is None else Rs[gated])
            accepted[gated] = nis <= np.array([bounds[j] for j in gated], dtype=float)
        used = np.flatnonzero(accepted)
        if used.size == 0:
            return accepted, None
        cols, H, y = stack_rows([rows[j] for j in used], zs[used])
        R_joint = block_diagonal(Rs[used] if Rs is not None else [R] * used.size)
        result = ekf.update_sparse(self.x, self.P, y, cols, H, R_joint, frozen=self.frozen())
        result = self._iterate(result, [landmark_ids[j] for j in used], zs[used], R_joint, cols)
        self.x, self.P = result.x, result.P
        return accepted, result

    def observation_nis(self, landmark_ids, zs_robot, R) -> np.ndarray:
        """NIS yᵢᵀSᵢ⁻¹yᵢ (k,) of each observation z (k, 3) on its own, against the current state.

        Sᵢ = Hᵢ P Hᵢᵀ + Rᵢ is its marginal innovation covariance (the gate of
        :meth:`update_landmarks`); ``R`` is (3, 3) for all or (k, 3, 3).
        """
        rows = self.predict_observations(landmark_ids)
        zs = np.asarray(zs_robot, dtype=float).reshape(len(rows), 3)
        return self._nis(rows, zs, np.asarray(R, dtype=float))

    def innovation_covariances(self, landmark_ids, Rs) -> list:
        """S = H P Hᵀ + R (3, 3) of an observation of each landmark, noise ``Rs[n]``, against the state (SPEC 5.3)."""
        rows = [row[1:] for row in self.predict_observations(landmark_ids)]  # (cols, H): one stacked product per size
        return ekf.innovation_covariances_sparse(self.P, [r[0] for r in rows], [r[1] for r in rows], Rs)

    def _nis(self, rows, zs, R) -> np.ndarray:
        """NIS of predicted-observation ``rows`` (z_hat, cols, H_cols), each on its own (:func:`ekf.nis_sparse`)."""
        y = zs - np.array([z_hat for z_hat, _, _ in rows]).reshape(-1, 3)
        return ekf.nis_sparse(self.P, y, [cols for _, cols, _ in rows], [H for _, _, H in rows], R)

    # ------------------------------------------------------------ augmentation
    @journaled
    def add_landmark(self, landmark_id, block, z_robot, R) -> None:
        """Initialise ``block`` from the first observation z (3,) (robot frame) with noise R (3, 3).

        m = R(θ) z + [x, y, 0]ᵀ with Jacobians J_pose, J_z; the block mean is
        x_b(m) with D = ∂x_b/∂m, so A = D J_pose and B = D J_z give
        P_bb = A P_rr Aᵀ + B R Bᵀ + prior and P_{·,b} = P_{·,r} Aᵀ — the
        robot's uncertainty propagated into the new block.
        """
        if landmark_id in self._blocks:
            raise KeyError(f"landmark {landmark_id!r} is already in the state")
        m, J_pose, J_z = point_from_observation(self.x[:3], z_robot)
        x_b, D, prior = block.initial(m)
        self._append(landmark_id, block, x_b, D @ J_pose, D @ J_z @ R @ J_z.T @ D.T + prior)

    def _append(self, landmark_id, block, x_b, A, extra_cov) -> None:
        """Append block mean x_b with covariance A P_rr Aᵀ + extra_cov and cross-covariance P_{·,r} Aᵀ."""
        cross = self.P[:, :3] @ A.T
        P_bb = A @ self.P[:3, :3] @ A.T + extra_cov
        start = self.x.size
        self.x, self.P = ekf.augment(self.x, self.P, x_b, 0.5 * (P_bb + P_bb.T), cross)
        self._blocks[landmark_id] = (start, block)
        if self._groups is not None:
            self._groups = self._groups.appended(start, block)
        if getattr(block, "frozen", ()):
            self._frozen = None  # (the indices of the blocks before it stay)

    @journaled
    def remove_landmark(self, landmark_id) -> None:
        """Drop a landmark's block (marginalising it out of x and P)."""
        removed_start, removed = self._blocks.pop(landmark_id)
        size = removed.size  # (a property: read once, not once per block kept)
        self.x, self.P = ekf.marginalise_range(self.x, self.P, removed_start, removed_start + size)
        self._blocks = {
            key: (start - size if start > removed_start else start, block)
            for key, (start, block) in self._blocks.items()
        }
        self._groups = self._frozen = None

    @journaled
    def replace_block(self, landmark_id, new_block, x_new, J, extra_cov) -> None:
        """Convert a landmark's block: x_new = g(x_b) with J = ∂g/∂x_b (k_new, k_old).

        The new block's covariance is J P_bb Jᵀ + extra_cov and its
        cross-covariance with the rest of the state J P_{b,·}; the block moves to
        the end of the state.
        """
        idx = self.indices(landmark_id)
        keep = np.delete(np.arange(self.x.size), idx)  # (np.setdiff1d's result, without its sort)
        J = np.atleast_2d(np.asarray(J, dtype=float))
        cross = self.P[np.ix_(keep, idx)] @ J.T
        P_new = J @ self.P[np.ix_(idx, idx)] @ J.T + extra_cov
        self.remove_landmark(landmark_id)
        start = self.x.size
        self.x, self.P = ekf.augment(self.x, self.P, np.asarray(x_new, dtype=float),
                                     0.5 * (P_new + P_new.T), cross)
        self._blocks[landmark_id] = (start, new_block)
        self._groups = self._frozen = None

    @journaled
    def couple_to_pose(self, landmark_id, rows, A, extra_cov) -> None:
        """Give entries ``rows`` (r,) of a landmark's block, so far exact (zero rows and columns of P), the error
        A e_pose + ν: covariance A P_rr Aᵀ + ``extra_cov`` (r, r) and cross-covariance A P_{r,·}, as
        :meth:`add_landmark` places a point through the pose (A (r, 3))."""
        idx = self.indices(landmark_id)[np.asarray(rows)]
        A = np.asarray(A, dtype=float)
        P = self.P.copy()
        P[idx, :] = A @ self.P[:3, :]
        P[:, idx] = P[idx, :].T
        block = A @ self.P[:3, :3] @ A.T + extra_cov
        P[np.ix_(idx, idx)] = 0.5 * (block + block.T)
        self.P = P

