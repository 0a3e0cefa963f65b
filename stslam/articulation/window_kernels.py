"""Compiled loops of a window's evidence (SPEC 13, 18): :func:`stslam.articulation.window_evidence.rest_means`
walks a window point by point, once per landmark whose window changed at every revision.

The same IEEE operations in the same order as the formulas they implement (numba does not reorder
floating-point arithmetic without ``fastmath``), so the same numbers; compiled (cached on disk)
because a Python loop over a window's points is most of the call.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def rest_runs(points, variances, limit):
    """Runs of observations at rest (:func:`~stslam.articulation.window_evidence.rest_means`): each run's
    mean (m, 3) and its summed weight Σ 1/v (m,). An observation (n, 3) with variance v (n,) joins the
    current run while its squared distance from the run's mean is at most ``limit`` · v."""
    n = points.shape[0]
    means = np.empty((n, 3))
    weights = np.empty(n)
    m = 0
    tx = ty = tz = weight = 0.0
    for i in range(n):
        x, y, z, v = points[i, 0], points[i, 1], points[i, 2], variances[i]
        if weight > 0.0:
            mx, my, mz = tx / weight, ty / weight, tz / weight
            dx, dy, dz = x - mx, y - my, z - mz
            if dx * dx + dy * dy + dz * dz > limit * v:
                means[m, 0], means[m, 1], means[m, 2] = mx, my, mz
                weights[m] = weight
                m += 1
                tx = ty = tz = weight = 0.0
        tx, ty, tz, weight = tx + x / v, ty + y / v, tz + z / v, weight + 1.0 / v
    means[m, 0], means[m, 1], means[m, 2] = tx / weight, ty / weight, tz / weight
    weights[m] = weight
    return means[:m + 1].copy(), weights[:m + 1].copy()
