"""What a resting selector keeps (``quiet_static``, docs/selection.md §7): its motion test's fits, and its refits.

The motion test's noise variance σ̂² (:func:`stslam.articulation.evidence.noise_variance`)
comes from the line and circle structures of the latest refit. A resting
selector neither steps its filter bank nor refits the filters' structures, but
its test must stay the one it would be awake, or a static point seen through a
slowly drifting pose would be judged against the noise of its first few
observations and woken by a wander its later fits explain: the structures'
fits are redone on the same schedule, on the same window, and only their
residuals kept. Each of those refits' step and window is kept too: on waking,
the bank steps through the observations it rested over with the refits made
where they were due, so that it is then the bank that never rested.
"""

from __future__ import annotations

import numpy as np

from stslam.articulation.evidence import noise_variance
from stslam.errors import DegenerateFitError


class RestingFits:
    """Residuals (m) and point counts of the moving models' structures refitted while resting, and the refits.

    ``version`` changes with every refit or :meth:`end`, so a cached σ̂² knows when to be recomputed.
    """

    def __init__(self):
        self.fits: dict[str, tuple[float, int]] = {}
        self.version = 0
        self._left_out: set = set()  # models whose fit was not needed at the latest refit (floor reached)
        self.start = None  # the first observation the bank rested over
        # observation count at a due refit → (its fit window, model name → the structure fitted on it)
        self.refits: dict[int, tuple[np.ndarray, dict]] = {}

    def begin(self, n: int) -> None:
        """Rest from observation ``n`` (0-based) on."""
        self.start, self.refits = n, {}

    def end(self) -> tuple[int, dict]:
        """Awake again: the first observation rested over and the refits due since; the fits are dropped
        (the filters' own structures, once refitted, are current)."""
        out = (self.start, self.refits)
        self.fits, self.start, self.refits, self._left_out = {}, None, {}, set()
        self.version += 1
        return out

    def refit(self, filters, fit_window: np.ndarray, log_mu: np.ndarray, selector: str, n: int,
              sigma_m: float) -> None:
        """At a due refit with ``n`` observations: fit the moving models the refit would (under ``threshold``,
        those of μ > 0) on ``fit_window``, and note the refit with the structures fitted (waking, the
        refit there takes them instead of fitting the same window again: the same structures).

        A degenerate fit, or a circle below its filter's ``min_radius_m``, keeps the previous
        residual, as a refit keeps the previous structure (:meth:`ModelFilter.prepare`). The
        circle, the costly fit, is left out when the others already bring σ̂² to its floor σ_z²
        (``sigma_m``): σ̂² = max(σ_z², min over the fits) is then σ_z² whatever the circle's residual.
        """
        order = sorted(range(len(filters)), key=lambda j: filters[j].name == "revolute")  # the circle last
        self._left_out, fresh, structures = set(), [], {}
        for j in order:
            f = filters[j]
            if f.name == "static" or (not np.isfinite(log_mu[j]) and selector == "threshold"):
                continue
            if f.name == "revolute" and fresh and noise_variance(fresh, sigma_m) == sigma_m ** 2:
                self._left_out.add(f.name)  # this refit's other fits bring σ̂² to its floor already
                continue
            try:
                structure = f.model.fit(fit_window)
            except DegenerateFitError:
                continue
            structures[f.name] = structure
            radius = getattr(structure, "radius", None)
            if radius is not None and radius < f.settings.min_radius_m:
                continue
            self.fits[f.name] = (structure.residual_m, fit_window.shape[0])
            fresh.append((f.name, *self.fits[f.name]))
        self.refits[n] = (fit_window, structures)
        self.version += 1

    def noise_fits(self, filters) -> list:
        """(model name, RMS residual, n points) of each moving model's latest fit, for noise_variance
        (without the models left out at the latest refit)."""
        out = []
        for f in filters:
            if f.name == "static" or f.name in self._left_out:
                continue
            if f.name in self.fits:
                out.append((f.name, *self.fits[f.name]))
            elif f.structure is not None:
                out.append((f.name, f.structure.residual_m, f.n_fit))
        return out
