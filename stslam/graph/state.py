"""The SLAM state held in an iSAM2 smoother, driven by the same frame loop and policies as the EKF (SPEC 14).

:class:`GraphState` answers what :func:`stslam.slam.loop.run_slam` and the
filters' policies ask of :class:`~stslam.slam.core.SlamState` (pose and its
covariance, observation NIS, gated updates, adding, converting and removing
landmark blocks), but every step adds variables and factors to a GTSAM
``ISAM2`` instead of changing a mean and covariance:

* variables: the pose x_k of every frame, and per landmark a chain of its
  block's state (:mod:`stslam.slam.blocks`) at the frames where it is used.
  A block without a transition (a static point with no walk) is one variable;
  any other gets a new variable at each frame it is touched, tied to the
  previous one by its transition composed over the gap (F = Π F_t,
  Q = Σ F Q_t Fᵀ: SPEC 3's X_{t+1} = A X_t + B η, Dyn. SLAM's constant
  velocity, a random walk). The structure of an articulated block is fixed
  inside the block (fixed at conversion, replaced at each refit), as in the EKF;
* factors (:mod:`stslam.graph.factors`): a prior on x_0, odometry with the
  covariance the EKF predicts with (V S Vᵀ [+ Q₂], SPEC 5.1), one observation
  factor per accepted observation, the transitions, the selected prior of a
  new block (what one point cannot tell), a linear factor x_new = J x_old + c per conversion;
* singular covariances (a known first pose, σ_η = 0, a conversion that keeps q exactly) get ``floor_sigma``² I;
* gates are the EKF's χ² tests, on iSAM2's joint marginal of the current pose
  and the landmarks' states at the current frame: a gated observation never
  becomes a factor (a gate, not a robust kernel, so that the gated baseline
  and A-SLAM reject exactly what their EKF versions would given the same
  estimate, and a rejected moving landmark cannot pull the smoothed past).

Factors are buffered and handed to iSAM2 (one ``update``) when an estimate or
covariance they can change is asked for: gates read the frame's prior marginals
(:mod:`stslam.graph.prior`) and a prediction or conversion alone changes no held
variable (:meth:`GraphState._sync`), so a frame costs one update, re-reads included.
The causal estimate is what :attr:`pose` says at each frame; :meth:`smoothed` is the final trajectory.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from stslam.graph import factors
from stslam.graph.observing import StructureKeys, add_observation, innovations, local_state
from stslam.graph.prior import HeldJoints, Predictions, near_keys
from stslam.graph.solver import Isam2Settings, key_letter, make_solver
from stslam.graph.regate import finish
from stslam.graph.reread import (Chain, Pending, is_restart, is_static_to_articulated, offer, reread_pending,
                                 rereadable, withdraw)
from stslam.robot.motion import motion_jacobians, move, second_order_motion_noise
from stslam.robot.sensor import point_from_observation
from stslam.slam.core import LandmarkTable, SlamState


@dataclass(frozen=True)
class Accepted:
    """The outcome of :meth:`GraphState.update_landmark` (``accepted`` as in :class:`stslam.kalman.ekf.Update`)."""

    accepted: bool


def pose_key(k: int) -> int:
    import gtsam

    return gtsam.symbol("x", k)


class GraphState(LandmarkTable):
    """Robot poses and landmark block chains in iSAM2 (module docstring); one run, frame by frame.

    ``pose_xytheta`` (3,): the first pose, ``pose_cov`` (3, 3) its covariance (zero: known, floored);
    ``motion_order`` 1 or 2: odometry covariance V S Vᵀ, or plus Q₂ (as :class:`~stslam.slam.core.SlamState`).
    """

    def __init__(self, pose_xytheta, pose_cov, motion_order: int = 2, settings: Isam2Settings = Isam2Settings()):
        import gtsam

        if motion_order not in (1, 2):
            raise ValueError(f"motion_order: expected 1 or 2, got {motion_order!r}")
        self.motion_order, self.settings = motion_order, settings
        self._solver = make_solver(settings)
        self._graph, self._values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        self._guess: dict = {}  # key -> value, for keys not yet in iSAM2 or estimated since the last update
        self._heads: dict = {}  # landmark id -> (key, frame, block): the block's latest variable
        self._chains: dict = {}  # landmark id -> its current Chain (stslam.graph.reread)
        self._all_chains: list = []  # every Chain of the run, in order of creation (stslam.graph.regate)
        self._retired: dict = {}  # landmark id -> (frame, Chain) of a chain just removed
        self._pending: dict = {}  # landmark id -> Pending re-read of its static past
        self._owners: list = []  # per buffered factor: the Chain it belongs to, or None
        self._removals: list = []  # iSAM2 factor indices to take out at the next update
        self._observed: set = set()  # keys with buffered observation factors of update_landmarks
        self._pred = Predictions(settings.floor_sigma)  # variables made since the last update as predictions
        self._structures = StructureKeys(settings.structure == "variable", settings.structure_sigma)  # δ (observing)
        self._n_keys, self._gate_marginals = 0, {}  # key -> its marginal at its latest gate (graph.regate's bounds)
        self._joints = HeldJoints()  # iSAM2's last joint marginal since its update
        self._leaves_only = True  # every buffered factor is a leaf (_add)
        self._relinearize_at = 0  # frame from which the next update checks relinearisation (relinearize_frames)
        self._dts: list = []
        self.k = 0
        self._new(pose_key(0), np.asarray(pose_xytheta, dtype=float))
        self._add(factors.pose_prior_factor(pose_key(0), pose_xytheta, pose_cov, settings.floor_sigma))

    # ------------------------------------------------------------ bookkeeping
    def _new(self, key, value, chain: Chain | None = None) -> None:
        self._values.insert(key, np.asarray(value, dtype=float))
        self._guess[key] = np.asarray(value, dtype=float).copy()
        if chain is not None:
            chain.keys.append(key)

    def _add(self, factor, chain: Chain | None = None, leaf: bool = False) -> None:
        """Buffer a factor; ``leaf``: the first on a variable made since the update, with an invertible Jacobian
        on it (a prediction, a conversion), so no held variable's estimate or marginal changes (:meth:`_sync`)."""
        self._graph.add(factor)
        self._owners.append(chain)
        self._leaves_only &= leaf

    def _sync(self, key, marginal: bool = True) -> None:
        """Flush, unless ``key``'s estimate (and iSAM2's marginal, if held) hold with the buffer (only leaves in it:
        the conversions and predictions since the last query then wait for the next update, not one their own)."""
        if not self._leaves_only or self._removals or (marginal and self._values.exists(key)):
            self._flush()

    def _flush(self) -> None:
        """Hand the buffered factors and variables to iSAM2 (one update) and forget the cached estimates."""
        import gtsam

        if self._graph.size() == 0 and self._values.size() == 0 and not self._removals:
            return
        heads = {key for key, _, _ in self._heads.values()}
        every = self.settings.relinearize_frames
        relinearize = every is not None and self.k >= self._relinearize_at
        if relinearize:  # the first update of every ``relinearize_frames``-th frame (Isam2Settings)
            self._relinearize_at = self.k + every
        indices = self._solver.update(self._graph, self._values, self._removals, float(np.sum(self._dts)), heads,
                                      relinearize)
        for chain, index in zip(self._owners, indices, strict=True):
            if chain is not None:
                chain.factor_indices.append(index)
        self._graph, self._values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        self._guess, self._owners, self._removals, self._observed = {}, [], [], set()
        self._joints.clear()
        self._leaves_only = True
        self._pred = Predictions(self.settings.floor_sigma)

    def value(self, key) -> np.ndarray:
        """Current estimate of variable ``key`` (the buffered guess, or iSAM2's estimate)."""
        if key not in self._guess:
            self._guess[key] = self._solver.estimate(key)
        return self._guess[key]

    def _landmark_key(self, block) -> int:
        """A new key for a variable of ``block`` (or of that many dimensions): its symbol's letter says which
        relinearisation threshold applies (:func:`stslam.graph.solver.key_letter`)."""
        import gtsam

        self._n_keys += 1
        return gtsam.symbol(key_letter(block), self._n_keys)

    # ------------------------------------------------------------ queries
    @property
    def pose(self) -> np.ndarray:
        """Robot pose estimate of the current frame (3,), after iSAM2 has taken every factor so far (that
        could change it: :meth:`_sync`)."""
        self._sync(pose_key(self.k))
        return self.value(pose_key(self.k)).copy()

    @property
    def pose_cov(self) -> np.ndarray:
        """Its marginal covariance (3, 3) from iSAM2."""
        self._sync(pose_key(self.k))
        return self._solver.marginal(pose_key(self.k))

    def _landmark_table(self) -> dict:
        return self._heads

    def _head(self, landmark_id) -> tuple:
        """(key, frame, block): the landmark's latest variable, its frame, and the block read on it."""
        return self._heads[landmark_id]

    def block_mean(self, landmark_id) -> np.ndarray:
        """The landmark's block state at the current frame (k,). A variable made since the last iSAM2 update
        and not yet updated by an observation is read as made (its guess: a new block from its first
        observation, a conversion's x̄', a prediction), as the EKF's mean after augmenting or converting;
        any other waits for the buffered factors (one iSAM2 update)."""
        key = self._advance(landmark_id)
        if not self._values.exists(key) or key in self._observed:
            self._sync(key)
        return self.value(key).copy()

    def landmark_position(self, landmark_id) -> tuple[np.ndarray, np.ndarray]:
        """World position m (3,) of a landmark at the current frame and its covariance (3, 3), first order: its
        latest variable carried over the gap by the block's transition, without adding a variable."""
        key, block, F, Q = self._carried(landmark_id)
        m, dm_dx = block.position(F @ self.value(key))
        return np.asarray(m, dtype=float), dm_dx @ (F @ self._solver.marginal(key) @ F.T + Q) @ dm_dx.T

    def landmark_point(self, landmark_id) -> np.ndarray:
        """m (3,) as :meth:`landmark_position` without the covariance (iSAM2's marginal, the costly part)."""
        key, block, F, _ = self._carried(landmark_id, marginal=False)
        return np.asarray(block.position(F @ self.value(key))[0], dtype=float)

    def _carried(self, landmark_id, marginal: bool = True) -> tuple:
        """(key, block, F, Q): the landmark's latest variable and the transition carrying it to this frame."""
        key, frame, block = self._head(landmark_id)
        self._sync(key, marginal)
        return (key, block, *self.transition_between(block, frame, self.k))

    def transition_between(self, block, frame: int, to_frame: int) -> tuple[np.ndarray, np.ndarray]:
        """Transition F and noise Q of ``block`` composed from ``frame`` to ``to_frame``."""
        F, Q = np.eye(block.size), np.zeros((block.size, block.size))
        for dt in self._dts[frame:to_frame]:
            F_t, Q_t = block.transition(dt)
            F_t = np.eye(block.size) if F_t is None else F_t
            F, Q = F_t @ F, F_t @ Q @ F_t.T + (0.0 if Q_t is None else Q_t)
        return F, Q

    # ------------------------------------------------------------ prediction
    def predict(self, control_vw, control_cov, dt: float) -> None:
        """New pose variable x_{k+1} = g(x_k, u) with an odometry factor of covariance V S Vᵀ [+ Q₂] (SPEC 5.1)."""
        x = self.value(pose_key(self.k))
        _, V = motion_jacobians(x, control_vw, dt)
        Q = V @ control_cov @ V.T
        if self.motion_order == 2:
            Q = Q + second_order_motion_noise(x, control_vw, control_cov, dt)
        self._new(pose_key(self.k + 1), move(x, control_vw, dt))
        self._add(factors.odometry_factor(pose_key(self.k), pose_key(self.k + 1), control_vw, dt, Q,
                                          self.settings.floor_sigma))
        G, _ = motion_jacobians(x, control_vw, dt)
        self._pred.record(pose_key(self.k + 1), pose_key(self.k), G, Q, self._values.exists(pose_key(self.k)))
        self._dts.append(float(dt))
        self.k += 1

    def _advance(self, landmark_id) -> int:
        """The landmark's variable at the current frame: a new one tied by the composed transition if needed."""
        key, frame, block = self._heads[landmark_id]
        chain = self._chains[landmark_id]
        if frame == self.k:
            chain.at[self.k] = (key, block)
            return key
        F_t, Q_t = block.transition(self._dts[frame])
        static = F_t is None and Q_t is None  # a static block: one variable for all frames
        gone = self._solver.gone(key)
        if static and gone is None:
            self._heads[landmark_id] = (key, self.k, block)
            chain.at[self.k] = (key, block)
            return key
        F, Q = (np.eye(block.size), np.zeros((block.size, block.size))) if static else \
            self.transition_between(block, frame, self.k)
        new = self._landmark_key(block)
        self._new(new, F @ self.value(key), chain)
        chain.at[self.k] = (new, block)
        floor = self.settings.floor_sigma
        if gone is None:
            self._add(factors.linear_factor(key, new, F, np.zeros(block.size), Q, floor), chain, leaf=True)
            self._pred.record(new, key, F, Q, self._values.exists(key))
        else:  # its variable left the window: a prior from its last marginal, carried over the gap
            self._add(factors.selected_prior_factor(new, F @ gone[0], np.arange(block.size),
                                                    F @ gone[1] @ F.T + Q + floor**2 * np.eye(block.size), 0.0),
                      chain, leaf=True)
        self._heads[landmark_id] = (new, self.k, block)
        return new

    def joint(self, keys) -> np.ndarray:
        """The joint marginal covariance of ``keys`` before the factors buffered since the last update: propagated
        from iSAM2's without an update when they are predictions (:mod:`stslam.graph.prior`), else after one."""
        keys = list(keys)
        if not self._pred.covers(keys, self._values.exists):
            self._flush()
            return self._held_joint(keys)
        return self._pred.joint(keys, self._held_joint, lambda k: self.value(k).size)

    def _held_joint(self, keys) -> np.ndarray:
        """iSAM2's joint marginal of held ``keys``, cut from the last one since the update if that covers them
        (:class:`~stslam.graph.prior.HeldJoints`, :func:`~stslam.graph.prior.near_keys`)."""
        return self._joints.joint(keys, self._solver.joint, lambda k: self.value(k).size, lambda: near_keys(self))

    # ------------------------------------------------------------ observations
    def _local(self, landmark_ids) -> SlamState:
        """An EKF state of the current pose and these landmarks' blocks (:func:`stslam.graph.observing.local_state`)."""
        return local_state(self, landmark_ids)

    def observation_nis(self, landmark_ids, zs_robot, R) -> np.ndarray:
        """NIS yᵢᵀSᵢ⁻¹yᵢ (k,) of each observation on its own (the EKF's gate), all on one joint marginal of
        iSAM2 (:func:`stslam.graph.observing.innovations`)."""
        offer(self, landmark_ids, zs_robot, R)
        zs = np.asarray(zs_robot, dtype=float).reshape(len(landmark_ids), 3)
        Rs = np.broadcast_to(R, (len(landmark_ids), 3, 3))
        return np.array([e @ np.linalg.solve(S, e) for e, S in innovations(self, landmark_ids, zs, Rs)])

    def innovation_covariances(self, landmark_ids, Rs) -> list:
        """S (3, 3) of each landmark's observation as SlamState's, from one joint marginal of them all."""
        zs = np.zeros((len(landmark_ids), 3))  # S does not depend on z
        return [S for _, S in innovations(self, landmark_ids, zs, Rs)]

    def update_landmarks(self, landmark_ids, zs_robot, R, max_nis=None):
        """Observation factors for the observations that pass their gates (as ``SlamState.update_landmarks``).

        Returns (accepted (k,) bool, None): iSAM2 takes the factors at the next query.
        """
        zs = np.asarray(zs_robot, dtype=float).reshape(len(landmark_ids), 3)
        R = np.asarray(R, dtype=float)
        Rs = R if R.ndim == 3 else np.broadcast_to(R, (len(landmark_ids), 3, 3))
        reread_pending(self, landmark_ids, Rs)
        offer(self, landmark_ids, zs, Rs)
        accepted = np.ones(len(landmark_ids), dtype=bool)
        bounds = max_nis if isinstance(max_nis, (list, tuple, np.ndarray)) else [max_nis] * len(landmark_ids)
        gated = [j for j in range(len(landmark_ids)) if bounds[j] is not None]
        if gated:
            nis = self.observation_nis([landmark_ids[j] for j in gated], zs[gated], Rs[gated])
            accepted[gated] = nis <= np.array([bounds[j] for j in gated], dtype=float)
        for j in np.flatnonzero(accepted):
            i = landmark_ids[j]
            key = self._advance(i)
            self._observed.add(key)
            add_observation(self, self.k, key, self.block(i), zs[j], Rs[j], self._chains[i])
        return accepted, None

    def update_landmark(self, landmark_id, z_robot, R, max_nis: float | None = None) -> Accepted:
        """One observation (gated if ``max_nis``), as ``SlamState.update_landmark``."""
        accepted, _ = self.update_landmarks([landmark_id], np.reshape(z_robot, (1, 3)), R, max_nis)
        return Accepted(bool(accepted[0]))

    def withdraw(self, landmark_id, since: int) -> int:
        """Remove a static point's observation factors from frame ``since`` on (:func:`.reread.withdraw`)."""
        return withdraw(self, landmark_id, since)

    def update_each(self, landmark_ids, zs_robot, Rs, max_nis: float | None = None) -> np.ndarray:
        """Observations each gated on its own, as ``SlamState.update_each``, but all against the frame's prior
        marginals (one update, not one per observation). Accepted (k,) bool."""
        return self.update_landmarks(landmark_ids, zs_robot, Rs, max_nis)[0]

    def copy(self) -> SlamState:
        """A trial state: the EKF state of the current pose and the landmarks touched at this frame (A-SLAM's
        consensus check updates a copy with the frame's decided-static landmarks and asks their NIS again)."""
        return self._local([i for i, (_, frame, _) in self._heads.items() if frame == self.k])

    # ------------------------------------------------------------ blocks
    def add_landmark(self, landmark_id, block, z_robot, R) -> None:
        """A new block variable from the first observation: its observation factor and the block's prior."""
        if landmark_id in self._heads:
            raise KeyError(f"landmark {landmark_id!r} is already in the state")
        m, _, _ = point_from_observation(self.value(pose_key(self.k)), z_robot)  # the pose as it stands
        x_b, D, prior = block.initial(m)
        key = self._landmark_key(block)
        chain = self._chains[landmark_id] = Chain(block)
        self._all_chains.append(chain)
        self._new(key, x_b, chain)
        chain.at[self.k] = (key, block)
        self._heads[landmark_id] = (key, self.k, block)
        chain.offered[self.k] = (np.asarray(z_robot, dtype=float).copy(), np.asarray(R, dtype=float).copy())
        add_observation(self, self.k, key, block, z_robot, R, chain)
        rows = np.flatnonzero(np.diag(prior) > 0)
        if rows.size:
            self._add(factors.selected_prior_factor(key, x_b, rows, prior[np.ix_(rows, rows)], 0.0), chain)
        exact = np.flatnonzero((np.diag(prior) == 0) & ~np.any(D != 0, axis=1))  # e.g. a slip that starts at 0
        if exact.size:  # the EKF's zero variance: held at x_b by a prior of the floor's std
            self._add(factors.selected_prior_factor(key, x_b, exact, np.zeros((exact.size, exact.size)),
                                                    self.settings.floor_sigma), chain)
        frame, old = self._retired.pop(landmark_id, (None, None))
        if frame == self.k and is_static_to_articulated(old.block, block):
            old.moving = True  # its gated-out observations were of a moving point (regate)
        if frame == self.k and self.settings.reread_restarts and is_restart(old.block, block) and rereadable(old.block):
            chain.earlier = [*old.earlier, old]  # re-read with it if it is converted (reread)
        if self.settings.reread and not self._solver.windowed and frame == self.k and rereadable(old.block) \
                and is_static_to_articulated(old.block, block):
            self._pending[landmark_id] = Pending(old, block, self.k, key, np.asarray(R, dtype=float).copy())

    def remove_landmark(self, landmark_id) -> None:
        """The landmark's chain ends here (its variables and factors stay, unless a conversion re-reads them)."""
        del self._heads[landmark_id]
        self._retired[landmark_id] = (self.k, self._chains.pop(landmark_id))
        self._pending.pop(landmark_id, None)

    def replace_block(self, landmark_id, new_block, x_new, J, extra_cov) -> None:
        """Convert a block: new variable x' with x' = x̄' + J (x − x̄) + noise(extra_cov), x̄ its current estimate."""
        key = self._advance(landmark_id)
        x_old = self.block_mean(landmark_id)
        J = np.atleast_2d(np.asarray(J, dtype=float))
        x_new = np.asarray(x_new, dtype=float)
        new = self._landmark_key(new_block)
        chain = self._chains[landmark_id]
        self._new(new, x_new, chain)
        chain.at[self.k] = (new, new_block)
        self._add(factors.linear_factor(key, new, J, x_new - J @ x_old, extra_cov, self.settings.floor_sigma), chain,
                  leaf=True)
        self._pred.record(new, key, J, extra_cov, self._values.exists(key))  # a prediction too (prior module)
        self._heads[landmark_id] = (new, self.k, new_block)
        pending = self._pending.get(landmark_id)
        if pending is not None and pending.frame == self.k:  # the re-read past ends at the latest variable
            pending.target = new
        elif (self.settings.reread_refits and not self._solver.windowed and hasattr(new_block, "structure")
              and hasattr(self._chains[landmark_id].block, "structure")):  # a refit of an articulated block
            self._pending[landmark_id] = Pending(self._chains[landmark_id], new_block, self.k, new, None)

    # ------------------------------------------------------------ results
    def smoothed(self) -> tuple[np.ndarray, np.ndarray]:
        """The final trajectory (k+1, 3) and its marginal covariances (k+1, 3, 3) (regate.finish)."""
        return finish(self)


__all__ = ["Accepted", "GraphState", "Isam2Settings", "pose_key"]
