"""Settings of articulation model selection (SPEC 4).

The config block (``conf/selection/<option>.yaml``, key ``selection``; read by
:func:`stslam.config.selection.selection_from_config`)::

    selector: threshold        # threshold (Algorithm 1) | imm
    models: [static, prismatic, revolute]
    n_min: 7                   # observations before the structures are fitted
    tau: 0.6                   # decision threshold on μ
    stay_probability: 0.98     # imm: Π_ii
    min_motion_m: 0.0          # no decision before the track moved this far (m)
    min_radius_m: 0.0          # smaller fitted circles are no joint (degenerate)
    scale_cap_m: null          # cap on r when σ_η is turned into rad (null: no cap)
    hold_steps: 1              # μ_j > τ must hold this many consecutive steps (1: Algorithm 1)
    fit_spacing_m: 0.0         # thin the fit window to this spacing (m); 0 keeps all
    order: 1                   # temporal order k (SPEC 3)
    dt: 1.0                    # time step (s or frames) when no timestamps are given
    measurement_sigma_m: 0.04  # σ_z per coordinate (m)
    smoothing_sigma: 0.6       # samples (SPEC 3)
    init_window: 7             # observations the motion state is initialised from
    structure_inflation: 3.0   # κ: R = σ_z²(1 + κ·p/n) while C is fitted on n points
    structure_uncertainty: inflation  # inflation (κ above) | fisher (fit covariance propagated)
    support_alpha: 0.001       # a moving model is declared only once motion (and, for a circle,
                               # curvature) is significant at this level; null: off
    static_alpha: 0.05         # static is declared only while motion is not significant at this level; null: off
    sigma_eta: {static: …, prismatic: …, revolute: …}   # per model, model unit / time^(k+1)
    static_perturbation: paper # paper ([1,1,1] scalar) | isotropic (3D walk)   (SPEC 2.1)
    refit: {enabled: true, dense_until: 0, growth: 1.2, rerun_steps: 30, extent_floor_m: 0.0, converged: false}
    quiet_static: false        # rest the bank while static holds and the motion test does not reject

A model is added to selection by naming it in ``models`` and giving its
``sigma_eta``: the selector itself does not change. ``structure_uncertainty``,
``support_alpha`` and ``static_alpha`` may be left out of a config; they then
take the defaults above (those of :class:`SelectionSettings` and
:class:`~stslam.selection.model_filter.FilterSettings`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace

from stslam.articulation.models import MODEL_NAMES
from stslam.selection.model_filter import FilterSettings
from stslam.selection.nested_price import NestedPrice

SELECTORS = ("threshold", "imm")
STRUCTURE_UNCERTAINTIES = ("inflation", "fisher")


@dataclass(frozen=True)
class SelectionSettings:
    """Everything :class:`stslam.selection.selector.ModelSelector` needs (see the module docstring).

    ``filters`` maps a model name to its :class:`~stslam.selection.model_filter.FilterSettings`;
    ``model_options`` to keyword options of :func:`stslam.articulation.models.get_model`.
    Structures are fitted on the observations thinned so that each kept point
    is at least ``fit_spacing_m`` from the previously kept one (0 keeps all):
    a long rest then counts as a few points, not hundreds, so it neither
    dominates the fit nor shrinks the structure term of R (stslam.selection.model_filter).
    Refits (:mod:`stslam.selection.schedule`): structures are refitted on every past observation at each step
    while there are at most ``refit_dense_until`` of them, and afterwards
    whenever the count or the track's extent has grown by ``refit_growth``
    (the extent counted from at least ``refit_extent_floor_m``, so the jitter
    of a resting point does not trigger refits). ``refit_converged``: a refit
    that moved no (judged) structure by more than its own standard error
    doubles the next interval in the count, up to a growth of 2; the nested
    price has the same schedule of its own, thinned only once the track is settled.
    ``settle_steps`` (with a nested price): once static is ruled out by the motion
    guard and μ_static < 1 − τ has held this many steps past ``min_motion_m``,
    the filter bank stops (docs/selection.md §5). ``quiet_static``: while static is held and the
    motion test does not reject at ``support_alpha``, the bank and the structure refits rest
    (μ stays as it is); when it rejects, the bank steps through what it rested over, refits
    included, and goes on as if it had never rested (docs/selection.md §7).
    Decision guards (:meth:`stslam.selection.selector.ModelSelector.supported`): a
    moving model is declared only when the observations moved significantly
    at level ``support_alpha`` (and a revolute one only when its fit window
    supports a curvature at that level); static only while they did not move
    significantly at level ``static_alpha``; None turns a guard off.
    """

    models: tuple[str, ...]
    filters: dict[str, FilterSettings]
    model_options: dict[str, dict] = field(default_factory=dict)
    n_min: int = 7
    tau: float = 0.6
    selector: str = "threshold"
    stay_probability: float = 0.98
    min_motion_m: float = 0.0
    dt: float = 1.0
    measurement_sigma_m: float = 0.04
    refit: bool = True
    refit_dense_until: int = 0
    refit_growth: float = 1.2
    fit_spacing_m: float = 0.0
    hold_steps: int = 1
    support_alpha: float | None = 0.001
    static_alpha: float | None = 0.05
    revise: bool = False
    nested_price: NestedPrice | None = None
    outlier_nis: float | None = None
    settle_steps: int | None = None
    refit_extent_floor_m: float = 0.0
    refit_converged: bool = False
    quiet_static: bool = False

    def __post_init__(self):
        if self.quiet_static and (self.support_alpha is None or not self.refit):
            raise ValueError("quiet_static needs the motion guard (support_alpha) and refits (refit): "
                             f"got support_alpha={self.support_alpha!r}, refit={self.refit!r}")

    def with_dt(self, dt: float) -> "SelectionSettings":
        """A copy with time step ``dt``."""
        return replace(self, dt=float(dt))


def make_settings(sigma_eta: Mapping[str, float], *, models=MODEL_NAMES, order: int = FilterSettings.order,
                  measurement_sigma_m: float = FilterSettings.measurement_sigma_m,
                  smoothing_sigma: float = FilterSettings.smoothing_sigma,
                  init_window: int = FilterSettings.init_window,
                  structure_inflation: float = FilterSettings.structure_inflation,
                  rerun_steps: int = FilterSettings.rerun_steps, min_radius_m: float = FilterSettings.min_radius_m,
                  scale_cap_m: float = FilterSettings.scale_cap_m, static_perturbation: str = "paper",
                  structure_uncertainty: str = FilterSettings.structure_uncertainty,
                  fast_update: bool = FilterSettings.fast_update, **rest) -> SelectionSettings:
    """SelectionSettings from plain values (``rest``: the other fields of SelectionSettings).

    The per-model values default to :class:`~stslam.selection.model_filter.FilterSettings`'s.
    """
    filters = {name: FilterSettings(order=order, sigma_eta=float(sigma_eta[name]),
                                    measurement_sigma_m=measurement_sigma_m,
                                    smoothing_sigma=smoothing_sigma, init_window=init_window,
                                    structure_inflation=structure_inflation,
                                    structure_uncertainty=structure_uncertainty, rerun_steps=rerun_steps,
                                    min_radius_m=min_radius_m, scale_cap_m=scale_cap_m, fast_update=fast_update)
               for name in models}
    options = {"static": {"perturbation": static_perturbation}} if "static" in models else {}
    return SelectionSettings(models=tuple(models), filters=filters, model_options=options,
                             measurement_sigma_m=measurement_sigma_m, **rest)

