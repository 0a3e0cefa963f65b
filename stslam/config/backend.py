"""The SLAM back end of ``dynamic_slam`` and ``fridge`` from the config: ``backend`` and ``isam2.*`` (SPEC 14).

``backend: ekf`` (default) runs every filter on the EKF core
(:class:`stslam.slam.core.SlamState`); ``backend: isam2`` on the GTSAM iSAM2
smoother (:mod:`stslam.graph`), which needs the optional extra
``pip install -e ".[gtsam]"``. The ``isam2`` block fills
:class:`stslam.graph.state.Isam2Settings`; a key left out takes the field's default.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping

from stslam.config.readers import (field_default, get_bool, get_choice, get_float, get_int, get_name_list, get_optional,
                                   lookup)
from stslam.errors import ConfigError
from stslam.graph.run import backend_runner, gtsam_problem
from stslam.graph.state import Isam2Settings
from stslam.slam.filters import FILTER_NAMES

BACKENDS = ("ekf", "isam2")


def backend_from_config(cfg: Mapping) -> str:
    """``backend``: ``ekf`` (default) or ``isam2``; ``isam2`` without a usable gtsam is a ConfigError."""
    backend = get_choice(cfg, "backend", BACKENDS, default="ekf")
    if backend == "isam2" and (problem := gtsam_problem()) is not None:
        raise ConfigError(f'backend: isam2 needs gtsam ≥ 4.3, < 4.4 ({problem}): pip install -e ".[gtsam]" '
                          f'(or pip install "gtsam>=4.3,<4.4")')
    return backend


def isam2_from_config(cfg: Mapping) -> Isam2Settings:
    """Checked ``isam2.*`` values (:class:`~stslam.graph.state.Isam2Settings`)."""
    def default(name):
        return field_default(Isam2Settings, name)

    return Isam2Settings(
        relinearize_threshold=get_float(cfg, "isam2.relinearize_threshold", low=0.0, low_open=True,
                                        default=default("relinearize_threshold")),
        relinearize_threshold_m=get_float(cfg, "isam2.relinearize_threshold_m", low=0.0, low_open=True,
                                          default=default("relinearize_threshold_m")),
        relinearize_threshold_q=get_optional(get_float, cfg, "isam2.relinearize_threshold_q", low=0.0, low_open=True),
        relinearize_skip=get_int(cfg, "isam2.relinearize_skip", low=1, default=default("relinearize_skip")),
        relinearize_frames=get_optional(get_int, cfg, "isam2.relinearize_frames", low=1),
        floor_sigma=get_float(cfg, "isam2.floor_sigma", low=0.0, low_open=True, default=default("floor_sigma")),
        final_iterations=get_int(cfg, "isam2.final_iterations", low=0, high=100, default=default("final_iterations")),
        factorization=get_choice(cfg, "isam2.factorization", ("qr", "cholesky"), default=default("factorization")),
        reread=get_bool(cfg, "isam2.reread", default=default("reread")),
        reread_restarts=get_bool(cfg, "isam2.reread_restarts", default=default("reread_restarts")),
        reread_refits=get_bool(cfg, "isam2.reread_refits", default=default("reread_refits")),
        reread_refit_frames=get_int(cfg, "isam2.reread_refit_frames", low=1, default=default("reread_refit_frames")),
        structure=get_choice(cfg, "isam2.structure", ("fixed", "variable"), default=default("structure")),
        regate_probability=None if lookup(cfg, "isam2.regate_probability", default("regate_probability")) is None
        else get_float(cfg, "isam2.regate_probability", low=0.0, high=1.0, low_open=True, high_open=True,
                       default=default("regate_probability")),
        regate_robust=get_bool(cfg, "isam2.regate_robust", default=default("regate_robust")),
        observe_every=get_int(cfg, "isam2.observe_every", low=1, default=default("observe_every")),
        structure_sigma=get_float(cfg, "isam2.structure_sigma", low=0.0, low_open=True,
                                  default=default("structure_sigma")),
        structure_sigma_final=get_optional(get_float, cfg, "isam2.structure_sigma_final", low=0.0, low_open=True),
        lag_s=get_optional(get_float, cfg, "isam2.lag_s", low=0.0, low_open=True),
        windowed=tuple(get_name_list(cfg, "isam2.windowed", FILTER_NAMES) if lookup(cfg, "isam2.windowed", [])
                       else ()),
    )


def backend_description(cfg: Mapping) -> str:
    """One line for a run's header: the back end, and under iSAM2 which methods run over the fixed lag."""
    if backend_from_config(cfg) == "ekf":
        return "back end: EKF"
    settings = isam2_from_config(cfg)
    run = lookup(cfg, "methods", None)
    windowed = [m for m in settings.windowed if run is None or m in run]
    if settings.lag_s is None or not windowed:
        return "back end: iSAM2 (every method over the whole run)"
    return (f"back end: iSAM2 ({', '.join(windowed)} over a fixed lag of {settings.lag_s:g} s "
            f"(isam2.windowed, isam2.lag_s); the others over the whole run)")


def backend_runner_from_config(cfg: Mapping) -> Callable:
    """``run(spec, inputs)`` of the configured back end (:func:`stslam.graph.run.backend_runner`)."""
    backend = backend_from_config(cfg)
    return backend_runner(backend, isam2_from_config(cfg) if backend == "isam2" else None)
