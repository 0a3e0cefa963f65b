"""Articulation model selection from its config block (``conf/selection/<option>.yaml``; SPEC 4).

The keys are listed in :mod:`stslam.selection.settings`; a key a config may
leave out takes the default of the settings dataclass it fills.
"""

from __future__ import annotations

from collections.abc import Mapping

from stslam.articulation.models import MODEL_NAMES
from stslam.config.readers import field_default, get_bool, get_choice, get_float, get_int, lookup
from stslam.errors import ConfigError
from stslam.selection.batch import BatchSettings
from stslam.selection.model_filter import FilterSettings
from stslam.selection.nested_price import NestedPrice
from stslam.selection.settings import SELECTORS, STRUCTURE_UNCERTAINTIES, SelectionSettings, make_settings


def _optional_float(cfg: Mapping, key: str) -> float:
    """A number > 0 at ``key``; null (or absent) means +inf."""
    if lookup(cfg, key, None) is None:
        return float("inf")
    return get_float(cfg, key, low=0.0, low_open=True)


def _optional_probability(cfg: Mapping, key: str, default: float) -> float | None:
    """A number in (0, 1) at ``key``; null means None (off); absent means ``default``."""
    if lookup(cfg, key, default) is None:
        return None
    return get_float(cfg, key, low=0.0, high=1.0, low_open=True, high_open=True, default=default)


def _nested_price(cfg: Mapping, key: str) -> NestedPrice | None:
    """The nested-model price at ``key`` (docs/selection.md §2); null or absent: none."""
    if lookup(cfg, key, None) is None:
        return None
    low = get_float(cfg, f"{key}.radius_min_m", low=0.0, low_open=True,
                    default=field_default(NestedPrice, "radius_min_m"))
    return NestedPrice(
        radius_min_m=low,
        radius_max_m=get_float(cfg, f"{key}.radius_max_m", low=low, low_open=True,
                               default=field_default(NestedPrice, "radius_max_m")),
        bend_sigma_per_m=get_float(cfg, f"{key}.bend_sigma_per_m", low=0.0,
                                   default=field_default(NestedPrice, "bend_sigma_per_m")),
        outlier_k=get_float(cfg, f"{key}.outlier_k", low=0.0, low_open=True,
                            default=field_default(NestedPrice, "outlier_k")))


def selection_from_config(cfg: Mapping, key: str = "selection", dt: float | None = None) -> SelectionSettings:
    """Read and check the selection block at ``key`` (ConfigError naming the bad entry).

    ``dt``, when given, replaces ``<key>.dt`` (the time step comes from the data).
    """
    models = lookup(cfg, f"{key}.models")
    if isinstance(models, str) or not isinstance(models, (list, tuple)) or not models:
        raise ConfigError(f"{key}.models: expected a non-empty list of model names, got {models!r}")
    for i, name in enumerate(models):
        if name not in MODEL_NAMES:
            raise ConfigError(f"{key}.models[{i}]: expected one of {', '.join(MODEL_NAMES)}; got {name!r}")
    if len(set(models)) != len(models):
        raise ConfigError(f"{key}.models: a model is listed twice: {models!r}")
    n_min = get_int(cfg, f"{key}.n_min", low=3)
    sigma_eta = {name: get_float(cfg, f"{key}.sigma_eta.{name}", low=0.0, low_open=True) for name in models}
    order = get_int(cfg, f"{key}.order", low=0, high=n_min - 2)
    step = get_float(cfg, f"{key}.dt", low=0.0, low_open=True) if dt is None else float(dt)
    return make_settings(
        sigma_eta,
        models=tuple(models),
        order=order,
        measurement_sigma_m=get_float(cfg, f"{key}.measurement_sigma_m", low=0.0, low_open=True),
        smoothing_sigma=get_float(cfg, f"{key}.smoothing_sigma", low=0.0, low_open=True),
        init_window=get_int(cfg, f"{key}.init_window", low=order + 2),
        structure_inflation=get_float(cfg, f"{key}.structure_inflation", low=0.0),
        structure_uncertainty=get_choice(cfg, f"{key}.structure_uncertainty", STRUCTURE_UNCERTAINTIES,
                                         default=field_default(FilterSettings, "structure_uncertainty")),
        support_alpha=_optional_probability(cfg, f"{key}.support_alpha",
                                            default=field_default(SelectionSettings, "support_alpha")),
        static_alpha=_optional_probability(cfg, f"{key}.static_alpha",
                                           default=field_default(SelectionSettings, "static_alpha")),
        rerun_steps=get_int(cfg, f"{key}.refit.rerun_steps", low=0),
        min_radius_m=get_float(cfg, f"{key}.min_radius_m", low=0.0),
        scale_cap_m=_optional_float(cfg, f"{key}.scale_cap_m"),
        fit_spacing_m=get_float(cfg, f"{key}.fit_spacing_m", low=0.0),
        hold_steps=get_int(cfg, f"{key}.hold_steps", low=1),
        static_perturbation=get_choice(cfg, f"{key}.static_perturbation", ("paper", "isotropic")),
        n_min=n_min,
        tau=get_float(cfg, f"{key}.tau", low=0.0, high=1.0, low_open=True, high_open=True),
        selector=get_choice(cfg, f"{key}.selector", SELECTORS),
        stay_probability=get_float(cfg, f"{key}.stay_probability", low=0.0, high=1.0, low_open=True),
        min_motion_m=get_float(cfg, f"{key}.min_motion_m", low=0.0),
        dt=step,
        refit=get_bool(cfg, f"{key}.refit.enabled"),
        refit_dense_until=get_int(cfg, f"{key}.refit.dense_until", low=0),
        refit_growth=get_float(cfg, f"{key}.refit.growth", low=1.0, low_open=True),
        revise=get_bool(cfg, f"{key}.revise", default=field_default(SelectionSettings, "revise")),
        nested_price=_nested_price(cfg, f"{key}.nested_price"),
        fast_update=get_bool(cfg, f"{key}.fast_update", default=field_default(FilterSettings, "fast_update")),
        refit_extent_floor_m=get_float(cfg, f"{key}.refit.extent_floor_m", low=0.0,
                                       default=field_default(SelectionSettings, "refit_extent_floor_m")),
        refit_converged=get_bool(cfg, f"{key}.refit.converged",
                                 default=field_default(SelectionSettings, "refit_converged")),
        quiet_static=get_bool(cfg, f"{key}.quiet_static", default=field_default(SelectionSettings, "quiet_static")),
        settle_steps=(None if lookup(cfg, f"{key}.settle_steps", None) is None
                      else get_int(cfg, f"{key}.settle_steps", low=0)),
        outlier_nis=(None if lookup(cfg, f"{key}.outlier_nis", None) is None
                     else get_float(cfg, f"{key}.outlier_nis", low=0.0, low_open=True)),
    )


def batch_from_config(cfg: Mapping, settings: SelectionSettings, key: str = "batch") -> BatchSettings | None:
    """The batch baseline at ``key`` (docs/selection.md §3), or None when ``<key>.enabled`` is false or absent.

    Its noise floor and thinning are the selection's ``measurement_sigma_m`` and ``fit_spacing_m``.
    """
    if not get_bool(cfg, f"{key}.enabled", default=False):
        return None
    return BatchSettings(sigma_m=settings.measurement_sigma_m, spacing_m=settings.fit_spacing_m,
                         inlier_k=get_float(cfg, f"{key}.inlier_k", low=0.0, low_open=True,
                                            default=field_default(BatchSettings, "inlier_k")),
                         iterations=get_int(cfg, f"{key}.iterations", low=1,
                                            default=field_default(BatchSettings, "iterations")),
                         seed=get_int(cfg, "seed", low=0, default=0))
