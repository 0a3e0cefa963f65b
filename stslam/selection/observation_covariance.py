"""Each observation's own covariance, for a selector fed points of varying quality (SPEC 13).

A point mapped to the world through an uncertain robot pose carries that
pose's share J_pose P_pose J_poseᵀ on top of the sensor's noise (SPEC 5.2,
SPEC 13). :meth:`stslam.selection.selector.ModelSelector.observe` takes such a
covariance with each observation; :class:`ObservationCovariances` holds them
(σ_z² I for points given without one) and answers the questions whose noise
they change: the filters' R (:meth:`stslam.selection.model_filter.ModelFilter.step`),
"has the point moved?" (:func:`stslam.articulation.evidence.weighted_motion_p_value`)
and the noise floor of the curvature test (:func:`~stslam.articulation.evidence.circle_support`).
Until the first covariance arrives it holds nothing and every answer is the
selector's own, computed as before.
"""

from __future__ import annotations

import math

import numpy as np

from scipy.special import chdtrc

from stslam.articulation.evidence import MotionStatistics
from stslam.selection.motion_sums_kernels import N_SUMS, add_point, motion_statistics


class ObservationCovariances:
    """The covariances (3, 3) (m², world frame) of a selector's observations, in order.

    Parameters
    ----------
    sigma_m : float
        σ_z (m): the covariance σ_z² I of observations given without one.

    Attributes
    ----------
    matrices : list of numpy.ndarray or None
        One per observation once a covariance was given; None before.
    """

    def __init__(self, sigma_m: float):
        self.sigma_m = float(sigma_m)
        self.matrices = None
        self._trace_sum = 0.0
        self._sums = None  # WeightedMotionSums of the motion test, for one excess variance

    def add(self, cov, n_before: int) -> None:
        """Note the covariance of the next observation (None: σ_z² I), the ``n_before``-th one (0-based)."""
        if cov is None and self.matrices is None:
            return
        c = self.sigma_m ** 2 * np.eye(3) if cov is None else np.asarray(cov, dtype=float)
        values = c.ravel().tolist() if c.shape == (3, 3) else None
        if values is None or not all(map(math.isfinite, values)):
            raise ValueError(f"an observation's covariance must be a finite (3, 3) array (m²), got {cov!r}")
        if self.matrices is None:
            self.matrices = [self.sigma_m ** 2 * np.eye(3)] * n_before
            self._trace_sum = 3.0 * self.sigma_m ** 2 * n_before
        self.matrices.append(c)
        self._trace_sum += (values[0] + values[4]) + values[8]  # the trace, summed in np.trace's order

    @property
    def sigma_floor_m(self) -> float:
        """Noise floor of the curvature test (m): σ_z, or √ of the mean per-coordinate variance (trace/3)."""
        if self.matrices is None:
            return self.sigma_m
        return math.sqrt(self._trace_sum / (3.0 * len(self.matrices)))

    def motion_p_value(self, motion: MotionStatistics, points_world, dts, noise_var: float) -> float:
        """p-value of "the point has not moved" with σ̂² = ``noise_var`` (m²).

        Without covariances, ``motion``'s (the running sums of the same points);
        with them, :func:`~stslam.articulation.evidence.weighted_motion_p_value`
        over ``points_world`` (n, 3) at the times ``dts`` (n,) add up to
        (``dts[0]`` unused), σ̂²'s excess over σ_z² added to every covariance,
        from running sums (:class:`WeightedMotionSums`): O(1) per new point while
        the excess is unchanged, O(n) when it changes.
        """
        if self.matrices is None:
            return motion.p_value(noise_var)
        excess = max(noise_var - self.sigma_m ** 2, 0.0)
        if self._sums is None or self._sums.excess_var != excess:
            self._sums = WeightedMotionSums(excess)
        self._sums.extend(points_world, dts, self.matrices)
        return self._sums.p_value()


class WeightedMotionSums:
    """:func:`~stslam.articulation.evidence.weighted_motion_p_value` of a growing track from running sums
    (SPEC 13; docs/selection.md §6).

    With W_i = (C_i + e I)⁻¹, times t_i and points z_i taken relative to the
    first observation's (which leaves both statistics unchanged and keeps the
    sums' cancellation small), the sums Σ W, Σ tW, Σ t²W, Σ Wz, Σ tWz, Σ zᵀWz
    and Σ t give, with t̄ = Σ t/n and τ = t − t̄,

        Σ τW = Σ tW − t̄ Σ W,  Σ τ²W = Σ t²W − 2t̄ Σ tW + t̄² Σ W,  Σ τWz = Σ tWz − t̄ Σ Wz,
        z̄ = (Σ W)⁻¹ Σ Wz,  spread = Σ zᵀWz − (Σ Wz)ᵀ z̄,
        Cov(b̂)⁻¹ = Σ τ²W − Σ τW (Σ W)⁻¹ Σ τW,  trend = rᵀ Cov(b̂) r,  r = Σ τWz − Σ τW z̄,

    the array form's quantities in other words. The 3 × 3 algebra is compiled
    (:mod:`stslam.selection.motion_sums_kernels`: a point costs a microsecond, not
    numpy's call overheads); a batch of points (a new excess) is summed with numpy.
    ``excess_var`` e is fixed: a new e needs new sums.
    """

    def __init__(self, excess_var: float):
        self.excess_var = float(excess_var)
        self.n = 0
        self._time = 0.0
        self._origin = None
        self._sums = np.zeros(N_SUMS)  # the kernels' layout (motion_sums_kernels)
        self._p = None  # p-value of the current n

    def extend(self, points_world, dts, covs) -> None:
        """Take the points ``points_world[self.n:]`` with their ``dts`` and covariances ``covs``."""
        n = len(points_world)
        if n <= self.n:
            return
        if self._origin is None:
            self._origin = np.asarray(points_world[0], dtype=float)
        times = []
        for i in range(self.n, n):
            self._time += float(dts[i]) if i > 0 else 0.0  # the selector's clock: δt summed in order
            times.append(self._time)
        if n - self.n > BATCH_POINTS:
            z = np.asarray(points_world[self.n:n], dtype=float) - self._origin
            self._sums = self._sums + _batch_sums(np.array(times), z, np.asarray(covs[self.n:n], dtype=float),
                                                  self.excess_var)
        else:
            o0, o1, o2 = self._origin.tolist()
            for i, t in zip(range(self.n, n), times):
                x0, x1, x2 = np.asarray(points_world[i], dtype=float).tolist()
                if not add_point(self._sums, t, x0 - o0, x1 - o1, x2 - o2, np.asarray(covs[i], dtype=float),
                                 self.excess_var):
                    raise np.linalg.LinAlgError("Singular matrix")
        self.n, self._p = n, None

    def p_value(self) -> float:
        """The p-value of the points taken so far (1 for fewer than 3)."""
        if self.n < 3:
            return 1.0
        if self._p is None:
            self._p = self._p_value()
        return self._p

    def _p_value(self) -> float:
        info_b, rhs = np.empty(9), np.empty(3)
        status, trend, rss = motion_statistics(self._sums, self.n, info_b, rhs)
        if status < 0:
            raise np.linalg.LinAlgError("Singular matrix")
        if status == 2:  # nearly singular: the array form's least squares
            trend = float(rhs @ np.linalg.lstsq(info_b.reshape(3, 3), rhs, rcond=None)[0])
        p_trend = float(chdtrc(3, trend))
        p_spread = float(chdtrc(3 * (self.n - 1), rss))
        return min(1.0, 2.0 * min(p_trend, p_spread))


# Above this many new points at once (a new excess variance), the sums are taken with numpy.
BATCH_POINTS = 8


def _batch_sums(times, z, covs, excess_var: float) -> np.ndarray:
    W = np.linalg.inv(covs + excess_var * np.eye(3))
    wz = np.einsum("nij,nj->ni", W, z)
    parts = (W.sum(axis=0), np.einsum("n,nij->ij", times, W), np.einsum("n,nij->ij", times * times, W),
             wz.sum(axis=0), times @ wz, np.einsum("ni,ni->", z, wz), times.sum())
    return np.concatenate([np.ravel(p) for p in parts])
