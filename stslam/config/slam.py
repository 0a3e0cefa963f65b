"""The SLAM filters' settings from the config (SPEC 6): ``filters.<name>``, ``selection``, the hinge axis.

``filters.<name>`` (``conf/exp/dynamic_slam.yaml`` with ``conf/tuning/<world>.yaml``,
``conf/exp/fridge.yaml``) gives the filter's settings dataclass
(:data:`stslam.slam.filters.FILTER_PARAMS`); ``motion_noise_order`` and
``update_iterations`` are shared by every filter (:class:`~stslam.slam.core.SlamState`).
A key a config may leave out takes the default of the dataclass field it fills.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import fields

from stslam.config.readers import (field_default, get_bool, get_choice, get_float, get_int, get_optional, lookup,
                                   optional_block)
from stslam.config.selection import selection_from_config
from stslam.errors import ConfigError
from stslam.graph.state import Isam2Settings
from stslam.articulation.hinge_axis import AxisTolerance, HingeAxisOptions
from stslam.slam.a_slam_settings import (ARTICULATED, ARTICULATED_UPDATES, EVIDENCE_POSES, SELECTION_COVARIANCES,
                                         STRUCTURE_PRIORS, STRUCTURE_STATES, ASlamParams, BodySettings)
from stslam.slam.filters import (FILTER_NAMES, DynSlamParams, EkfSlamParams, FilterSpec, GatedEkfSlamParams,
                                 OracleParams)


# AxisTolerance's fields stand as flat keys beside a block's own options (bodies, hinge-axis options)
TOLERANCE_KEYS = [f.name for f in fields(AxisTolerance)]


def filter_params_from_config(cfg: Mapping, name: str):
    """Checked settings of filter ``name`` (an instance of ``FILTER_PARAMS[name]``) from ``filters.<name>``."""
    key = f"filters.{name}"
    if name == "ekf_slam":
        return EkfSlamParams(sigma_walk=get_float(cfg, f"{key}.sigma_walk", low=0.0))
    if name == "ekf_slam_gated":
        return GatedEkfSlamParams(
            sigma_walk=get_float(cfg, f"{key}.sigma_walk", low=0.0),
            gate_probability=get_float(cfg, f"{key}.gate_probability", low=0.0, high=1.0,
                                       low_open=True, high_open=True))
    if name == "dyn_slam":
        return DynSlamParams(sigma_acc=get_float(cfg, f"{key}.sigma_acc", low=0.0),
                             sigma_v0=get_float(cfg, f"{key}.sigma_v0", low=0.0))
    if name == "oracle":
        return OracleParams(order=get_int(cfg, f"{key}.order", low=0, high=4),
                            sigma_eta_m=get_float(cfg, f"{key}.sigma_eta_m", low=0.0),
                            sigma_eta_rad=get_float(cfg, f"{key}.sigma_eta_rad", low=0.0),
                            sigma_rate0_m=get_float(cfg, f"{key}.sigma_rate0_m", low=0.0),
                            sigma_rate0_rad=get_float(cfg, f"{key}.sigma_rate0_rad", low=0.0),
                            sigma_eta_static_m=get_optional(get_float, cfg, f"{key}.sigma_eta_static_m", low=0.0))
    if name in ("a_slam", "a_slam_truth_onsets"):  # the bound runs A-SLAM's own settings (filters.a_slam)
        return a_slam_from_config(cfg)
    raise ConfigError(f"methods: expected names from {', '.join(FILTER_NAMES)}; got {name!r}")


def motion_noise_order_from_config(cfg: Mapping) -> int:
    """``motion_noise_order`` (1 or 2): how the control noise enters every filter's prediction."""
    return get_int(cfg, "motion_noise_order", low=1, high=2, default=field_default(FilterSpec, "motion_order"))


def update_iterations_from_config(cfg: Mapping) -> int:
    """``update_iterations`` (1 … 20): linearisations per update, 1 = EKF."""
    return get_int(cfg, "update_iterations", low=1, high=20, default=field_default(FilterSpec, "update_iterations"))


def a_slam_from_config(cfg: Mapping) -> ASlamParams:
    """Checked :class:`~stslam.slam.a_slam_settings.ASlamParams` from ``filters.a_slam`` and ``selection``."""
    key = "filters.a_slam"
    selection = selection_from_config(cfg, "selection")
    for name in ARTICULATED:
        if name not in selection.models:
            raise ConfigError(f"selection.models: A-SLAM needs {name!r} among the models, "
                              f"got {list(selection.models)}")
    slip = get_float(cfg, f"{key}.sigma_slip_m", low=0.0, default=field_default(ASlamParams, "sigma_slip_m"))
    structure = lookup(cfg, "isam2.structure", field_default(Isam2Settings, "structure"))
    if slip > 0.0 and lookup(cfg, "backend", "ekf") == "isam2" and structure != "fixed":
        raise ConfigError(f"{key}.sigma_slip_m: expected 0 with isam2.structure: variable (a structure "
                          f"variable and a slip on one block are not built), got {slip}")
    if slip > 0.0 and (state := lookup(cfg, f"{key}.structure_state", "fixed")) != "fixed":
        raise ConfigError(f"{key}.sigma_slip_m: expected 0 with {key}.structure_state: {state} (a block "
                          f"with both a slip and a structure correction is not built), got {slip}")
    if slip > 0.0 and lookup(cfg, f"{key}.bodies", None) is not None:
        raise ConfigError(f"{key}.sigma_slip_m: expected 0 with {key}.bodies (a body's members share one "
                          f"motion state; a slip per member is not built), got {slip}")
    return ASlamParams(
        selection=selection,
        sigma_walk=get_float(cfg, f"{key}.sigma_walk", low=0.0),
        gate_probability=get_float(cfg, f"{key}.gate_probability", low=0.0, high=1.0, low_open=True,
                                   high_open=True),
        sigma_eta_m=get_float(cfg, f"{key}.sigma_eta_m", low=0.0),
        sigma_eta_rad=get_float(cfg, f"{key}.sigma_eta_rad", low=0.0),
        sigma_rate0_m=get_float(cfg, f"{key}.sigma_rate0_m", low=0.0),
        sigma_rate0_rad=get_float(cfg, f"{key}.sigma_rate0_rad", low=0.0),
        structure_inflation=get_float(cfg, f"{key}.structure_inflation", low=0.0),
        refine_until=get_int(cfg, f"{key}.refine_until", low=0),
        restart_after=get_int(cfg, f"{key}.restart_after", low=1),
        max_pose_sigma_m=_max_pose_sigma(cfg, f"{key}.max_pose_sigma_m"),
        selection_covariance=get_choice(cfg, f"{key}.selection_covariance", SELECTION_COVARIANCES,
                                        default=field_default(ASlamParams, "selection_covariance")),
        moved_m=get_float(cfg, f"{key}.moved_m", low=0.0),
        static_hold=get_int(cfg, f"{key}.static_hold", low=1, default=field_default(ASlamParams, "static_hold")),
        convert=_convert_models(cfg, f"{key}.convert"),
        classify_every=get_int(cfg, f"{key}.classify_every", low=1,
                               default=field_default(ASlamParams, "classify_every")),
        common_axis=_common_axis_options(cfg, f"{key}.common_axis"),
        bodies=_body_settings(cfg, f"{key}.bodies"),
        block_order=None if lookup(cfg, f"{key}.block_order", None) is None
        else get_int(cfg, f"{key}.block_order", low=0, high=4),
        structure_state=get_choice(cfg, f"{key}.structure_state", STRUCTURE_STATES,
                                   default=field_default(ASlamParams, "structure_state")),
        structure_prior=get_choice(cfg, f"{key}.structure_prior", STRUCTURE_PRIORS,
                                   default=field_default(ASlamParams, "structure_prior")),
        sigma_slip_m=slip,
        onset_allowance=None if lookup(cfg, f"{key}.onset_allowance", 0.0) is None
        else get_float(cfg, f"{key}.onset_allowance", low=0.0, low_open=True,
                       default=field_default(ASlamParams, "onset_allowance")),
        onset_threshold=get_float(cfg, f"{key}.onset_threshold", low=0.0, low_open=True,
                                  default=field_default(ASlamParams, "onset_threshold")),
        onset_quiet=get_int(cfg, f"{key}.onset_quiet", low=1, default=field_default(ASlamParams, "onset_quiet")),
        onset_frame_quantile=get_float(cfg, f"{key}.onset_frame_quantile", low=0.0, high=1.0,
                                       default=field_default(ASlamParams, "onset_frame_quantile")),
        onset_drift_probability=None if lookup(cfg, f"{key}.onset_drift_probability", None) is None
        else get_float(cfg, f"{key}.onset_drift_probability", low=0.0, high=1.0, low_open=True, high_open=True),
        onset_windows=_onset_windows(cfg, f"{key}.onset_windows"),
        onset_window_probability=get_float(cfg, f"{key}.onset_window_probability", low=0.0, high=1.0,
                                           low_open=True, high_open=True,
                                           default=field_default(ASlamParams, "onset_window_probability")),
        onset_replay=get_int(cfg, f"{key}.onset_replay", low=0, default=field_default(ASlamParams, "onset_replay")),
        articulated_update=get_choice(cfg, f"{key}.articulated_update", ARTICULATED_UPDATES,
                                      default=field_default(ASlamParams, "articulated_update")),
        onset_withdraw=get_int(cfg, f"{key}.onset_withdraw", low=0,
                               default=field_default(ASlamParams, "onset_withdraw")),
    )


def _onset_windows(cfg: Mapping, key: str) -> tuple:
    """Window lengths of the shift test (positive integers); null or absent: () (off)."""
    value = lookup(cfg, key, None)
    if value is None:
        return ()
    if isinstance(value, (str, bytes)) or not all(isinstance(w, int) and not isinstance(w, bool) and w > 0
                                                  for w in value):
        raise ConfigError(f"{key}: expected a list of positive integers, got {value!r}")
    return tuple(int(w) for w in value)


def _axis_tolerance(cfg: Mapping, key: str, defaults: AxisTolerance | None) -> AxisTolerance:
    """:class:`~stslam.articulation.hinge_axis.AxisTolerance` from the flat keys ``<key>.max_angle_deg`` and
    ``<key>.max_distance_m`` (beside the block's other options); an absent key takes its value in ``defaults``
    (None: both are required)."""
    def default(name):
        return {} if defaults is None else {"default": getattr(defaults, name)}

    return AxisTolerance(
        max_angle_deg=get_float(cfg, f"{key}.max_angle_deg", low=0.0, low_open=True, high=90.0,
                                **default("max_angle_deg")),
        max_distance_m=get_float(cfg, f"{key}.max_distance_m", low=0.0, low_open=True, **default("max_distance_m")))


def _body_settings(cfg: Mapping, key: str) -> BodySettings | None:
    """Checked grouping options at ``key`` (SPEC 13; null or absent: None, every landmark on its own)."""
    own_keys = [f.name for f in fields(BodySettings) if f.name != "joint_tolerance"]
    if not optional_block(cfg, key, own_keys + TOLERANCE_KEYS, "body-grouping options"):
        return None

    def default(name):
        return {"default": field_default(BodySettings, name)}

    return BodySettings(
        significance=get_float(cfg, f"{key}.significance", low=0.0, high=1.0, low_open=True, high_open=True,
                               **default("significance")),
        window=get_int(cfg, f"{key}.window", low=2, **default("window")),
        min_common=get_int(cfg, f"{key}.min_common", low=2, **default("min_common")),
        min_motion_m=get_float(cfg, f"{key}.min_motion_m", low=0.0, **default("min_motion_m")),
        joint_tolerance=_axis_tolerance(cfg, key, AxisTolerance()),
        every=get_int(cfg, f"{key}.every", low=1, **default("every")),
        evidence_window=get_int(cfg, f"{key}.evidence_window", low=2, **default("evidence_window")),
        revision_margin=get_float(cfg, f"{key}.revision_margin", low=0.0, **default("revision_margin")),
        revise=get_bool(cfg, f"{key}.revise", **default("revise")),
        evidence_pose=get_choice(cfg, f"{key}.evidence_pose", EVIDENCE_POSES, **default("evidence_pose")))


def _max_pose_sigma(cfg: Mapping, key: str) -> float:
    """A number > 0 at ``key``; null means no guard (+inf); absent, the dataclass default."""
    value = lookup(cfg, key, field_default(ASlamParams, "max_pose_sigma_m"))
    return float("inf") if value is None else get_float(cfg, key, low=0.0, low_open=True, default=value)


def _convert_models(cfg: Mapping, key: str) -> tuple:
    """Articulated models to convert to (absent: the dataclass default, both); ConfigError naming ``key`` otherwise."""
    value = lookup(cfg, key, list(field_default(ASlamParams, "convert")))
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) or \
            any(m not in ARTICULATED for m in value) or len(set(value)) != len(value):
        raise ConfigError(f"{key}: expected a list of distinct models from {', '.join(ARTICULATED)}, got {value!r}")
    return tuple(m for m in ARTICULATED if m in value)


def _common_axis_options(cfg: Mapping, key: str) -> HingeAxisOptions | None:
    """Checked hinge-axis options at ``key`` (null or absent: None, each landmark keeps its own circle)."""
    own_keys = [f.name for f in fields(HingeAxisOptions) if f.name != "tolerance"]
    if not optional_block(cfg, key, own_keys + TOLERANCE_KEYS, "hinge-axis options"):
        return None
    return hinge_axis_from_config(cfg, key)


def hinge_axis_from_config(cfg: Mapping, key: str, defaults: bool = True) -> HingeAxisOptions:
    """Checked :class:`~stslam.articulation.hinge_axis.HingeAxisOptions` in the block at ``key``.

    With ``defaults`` an absent option takes the dataclass default; without, every option is required.
    """
    def default(name):
        return {"default": field_default(HingeAxisOptions, name)} if defaults else {}

    return HingeAxisOptions(
        tolerance=_axis_tolerance(cfg, key, field_default(HingeAxisOptions, "tolerance") if defaults else None),
        min_tracks=get_int(cfg, f"{key}.min_tracks", low=2, **default("min_tracks")),
        scale_m=get_float(cfg, f"{key}.scale_m", low=0.0, low_open=True, **default("scale_m")),
        trim_factor=get_float(cfg, f"{key}.trim_factor", low=1.0, **default("trim_factor")))
