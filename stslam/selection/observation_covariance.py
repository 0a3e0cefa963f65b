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

from stslam.articulation.evidence import MotionStatistics, weighted_motion_p_value


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

    def add(self, cov, n_before: int) -> None:
        """Note the covariance of the next observation (None: σ_z² I), the ``n_before``-th one (0-based)."""
        if cov is None and self.matrices is None:
            return
        c = self.sigma_m ** 2 * np.eye(3) if cov is None else np.asarray(cov, dtype=float)
        if c.shape != (3, 3) or not np.isfinite(c).all():
            raise ValueError(f"an observation's covariance must be a finite (3, 3) array (m²), got {cov!r}")
        if self.matrices is None:
            self.matrices = [self.sigma_m ** 2 * np.eye(3)] * n_before
            self._trace_sum = 3.0 * self.sigma_m ** 2 * n_before
        self.matrices.append(c)
        self._trace_sum += float(np.trace(c))

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
        (``dts[0]`` unused), σ̂²'s excess over σ_z² added to every covariance.
        """
        if self.matrices is None:
            return motion.p_value(noise_var)
        n = len(points_world)
        times = np.concatenate([[0.0], np.cumsum(np.asarray(dts[1:n], dtype=float))])
        return weighted_motion_p_value(points_world, times, np.array(self.matrices[:n]),
                                       max(noise_var - self.sigma_m ** 2, 0.0))
