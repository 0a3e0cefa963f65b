"""When the online selector refits its structures (SPEC 6.3(b)), and how far a refit moved them.

Refitting every structure at every step costs a fit per model per step; the
structures are refitted instead on a schedule that thins as the window grows
(n observations so far, extent e = the largest distance of any of them from
the first ones' mean):

    due  ⇔  n ≤ n_dense
          or  n ≥ g_k · n_last   and  e ≥ e_floor     (more observations; none while resting within the floor)
          or  e ≥ g · max(e_last, σ_z, e_floor)        (the point went somewhere new)

with n_last, e_last those of the latest refit. Without convergence thinning
g_k = g (``refit_growth``): O(log n) refits on a track of n observations.

Convergence thinning (``refit_converged``): a refit that moved every
refitted structure by less than that structure's own uncertainty
(:func:`structure_shift` < 1) found nothing the previous fit did not know,
so the next interval in the count doubles; one that moved a structure
further starts again from g:

    g_k = min(1 + 2^k (g − 1), 2),   k = refits in a row that moved no structure beyond its uncertainty

The cap 2 keeps every refit's window at least half new to the previous fit
(still O(log n) refits, with a larger base once the fits settle). The extent
trigger keeps g: a structure that has settled on its window says nothing of
the places the point has not been yet, where a short arc and a line part.

The shift of a structure C → C' is measured where it matters, on the fit
window: each point z is projected onto both structures, z ↦ f(C, q(C, z)),
and the RMS distance between the two projections is compared with the
standard error of a least-squares structure at an average point of its
window, σ̂·√(p/n) (p the structure's free parameters, n its fit points,
σ̂² the fits' noise variance floored at σ_z², :func:`stslam.articulation.evidence.noise_variance`;
the same predictive variance the inflation of R models,
:class:`stslam.selection.model_filter.FilterSettings`).
"""

from __future__ import annotations

import math

import numpy as np

from stslam.articulation.evidence import noise_variance

# Largest growth factor of the count or extent between two refits (module docstring).
MAX_GROWTH = 2.0


class RefitSchedule:
    """The refit schedule of one selector (module docstring).

    Parameters
    ----------
    growth : float
        g (> 1).
    dense_until : int
        n_dense: refit at every step while there are at most this many observations.
    extent_floor_m, sigma_m : float
        e_floor and σ_z (m).
    converged : bool
        Convergence thinning on or off.
    """

    def __init__(self, growth: float, dense_until: int, extent_floor_m: float, sigma_m: float, converged: bool):
        self.growth, self.dense_until = float(growth), int(dense_until)
        self.extent_floor_m, self.sigma_m, self.converged = float(extent_floor_m), float(sigma_m), bool(converged)
        self.n_last, self.extent_last = 0, 0.0
        self.quiet_run = 0  # k: refits in a row that moved no structure beyond its uncertainty
        self.count = 0  # refits so far

    @property
    def factor(self) -> float:
        """g_k."""
        if not self.converged or self.quiet_run == 0:
            return self.growth
        return min(1.0 + 2.0 ** self.quiet_run * (self.growth - 1.0), max(MAX_GROWTH, self.growth))

    def start(self, n: int, extent_m: float) -> None:
        """The structures were first fitted on ``n`` observations of extent ``extent_m``."""
        self.n_last, self.extent_last = int(n), float(extent_m)

    def due(self, n: int, extent_m: float) -> bool:
        """Whether to refit with ``n`` observations of extent ``extent_m``."""
        resting = extent_m < self.extent_floor_m  # nothing new to fit while within the floor
        return (n <= self.dense_until or (n >= self.factor * self.n_last and not resting)
                or extent_m >= self.growth * max(self.extent_last, self.sigma_m, self.extent_floor_m))

    def done(self, n: int, extent_m: float, quiet: bool) -> None:
        """A refit on ``n`` observations of extent ``extent_m``.

        ``quiet``: it moved no structure beyond its uncertainty; None (no structure refitted) keeps k.
        """
        self.n_last, self.extent_last = int(n), float(extent_m)
        if quiet is not None:
            self.quiet_run = self.quiet_run + 1 if quiet else 0
        self.count += 1


def structure_shift(model, old, new, window: np.ndarray, sigma_m: float, structure_dof: int) -> float:
    """RMS distance (in standard errors) between the projections of ``window`` (n, 3) on structures ``old`` and ``new``.

    Module docstring: the RMS over the window of ‖f(C', q(C', z)) − f(C, q(C, z))‖
    divided by σ·√(p/n), with σ = ``sigma_m`` (σ̂, m), p = ``structure_dof``
    and n the window's points.
    """
    n = window.shape[0]
    if n == 0 or structure_dof <= 0:
        return 0.0
    d = (model.position(new, model.motion_variable(new, window))
         - model.position(old, model.motion_variable(old, window)))
    rms = math.sqrt(float(np.add.reduce(d * d, axis=None)) / n)
    return rms / (sigma_m * math.sqrt(structure_dof / n))


def quiet_refit(old, filters, window: np.ndarray, sigma_m: float, rows) -> bool:
    """Whether a refit moved none of the structures of ``filters[j]``, j in ``rows``, beyond its uncertainty.

    :func:`structure_shift` < 1 from ``old[j]``, the structure before the refit (None: no
    quiet refit); σ̂ from every fit of ``filters`` floored at ``sigma_m``.
    """
    fits = [(f.name, f.structure.residual_m, f.n_fit) for f in filters if f.structure is not None]
    sigma = math.sqrt(noise_variance(fits, sigma_m))
    return all(old[j] is not None and structure_shift(filters[j].model, old[j], filters[j].structure, window, sigma,
                                                      filters[j].structure_dof) < 1.0 for j in sorted(rows))


def judged_models(names, log_mu: np.ndarray, supported, nested_price) -> set[int]:
    """Indices of the models whose structures' shifts decide whether a refit was quiet.

    Those the selector's guards allow (``supported(name)``): a model they rule out (static
    once the track has moved) cannot be declared, and its structure's precision decides
    nothing. With a nested price (not None), of prismatic and revolute only the one of
    larger μ (``log_mu``): the price decides between them, and their summed μ, which tells
    moving from resting, is the better predictor's.
    """
    rows = {j for j, name in enumerate(names) if supported(name)}
    if nested_price is not None and "prismatic" in names and "revolute" in names:
        i, j = names.index("prismatic"), names.index("revolute")
        rows.discard(j if log_mu[i] >= log_mu[j] else i)
    return rows
