"""Settings of A-SLAM (SPEC 6.3) and their checked reading from a config.

The config block ``filters.a_slam`` (``conf/exp/dynamic_slam.yaml``, its two
process noises per world in ``conf/tuning/<world>.yaml``; ``conf/exp/fridge.yaml``)
and the ``selection`` block (``conf/selection/slam.yaml``, ``rgbd_tracks.yaml``; SPEC 4).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from scipy.stats import chi2

from stslam.errors import ConfigError
from stslam.config.readers import get_float, get_int, lookup
from stslam.selection.settings import SelectionSettings, settings_from_config

ARTICULATED = ("prismatic", "revolute")
ANGULAR = ("revolute",)


@dataclass(frozen=True)
class ASlamParams:
    """A-SLAM settings (module docstring); units per frame when δt is one frame.

    Attributes
    ----------
    selection : SelectionSettings
        Model selection (SPEC 4); its ``order`` is also the order of the
        articulated motion states (SPEC 3).
    sigma_walk : float
        Random walk of static points (m/√s).
    gate_probability : float
        Probability of the χ² (3 dof) innovation gate on every observation.
    sigma_eta_m, sigma_eta_rad : float
        Process noise σ_η of prismatic q (m/s^(k+1)) and revolute φ (rad/s^(k+1)).
    sigma_rate0_m, sigma_rate0_rad : float
        Std added to the selector's rate estimates at conversion (m/s, rad/s).
    structure_inflation : float
        κ in R(1 + κ p/n) for articulated observations.
    refine_until : int
        Observations after which an articulated structure is no longer refitted.
    restart_after : int
        Consecutive gate rejections that restart a decided landmark.
    max_pose_sigma_m : float
        An observation is given to selection only when the robot's pose
        uncertainty moves its world point by at most this std (m, largest
        axis of J_pose P_pose J_poseᵀ).
    moved_m : float
        A landmark whose selector saw it this far (m) from where it started
        has been seen moving and is never made static again.
    convert : tuple of str
        Articulated models whose decision gives the landmark that model's
        block; a decision for another one is only recorded (the landmark stays
        an undecided gated static point and its selector is fed on).
    classify_every : int
        Only every n-th observation of a landmark goes to its selector.
    common_axis : dict or None
        Options of :func:`stslam.articulation.hinge_axis.estimate_hinge_axis`: a revolute
        landmark's structure is then its circle about the axis fitted jointly on
        every landmark held revolute (and waits, as a gated static point, until
        ``min_tracks`` of them agree); None: each landmark's own fitted circle.
    """

    selection: SelectionSettings
    sigma_walk: float
    gate_probability: float
    sigma_eta_m: float
    sigma_eta_rad: float
    sigma_rate0_m: float
    sigma_rate0_rad: float
    structure_inflation: float = 3.0
    refine_until: int = 60
    restart_after: int = 3
    max_pose_sigma_m: float = float("inf")
    moved_m: float = 0.2
    convert: tuple = ARTICULATED
    classify_every: int = 1
    common_axis: dict | None = None

    @property
    def max_nis(self) -> float:
        return float(chi2.ppf(self.gate_probability, 3))

    def sigma_eta(self, model_name: str) -> float:
        return self.sigma_eta_rad if model_name in ANGULAR else self.sigma_eta_m

    def sigma_rate0(self, model_name: str) -> float:
        return self.sigma_rate0_rad if model_name in ANGULAR else self.sigma_rate0_m


def a_slam_params(cfg: Mapping) -> ASlamParams:
    """Checked :class:`ASlamParams` from ``cfg["filters"]["a_slam"]`` and the ``selection`` block."""
    key = "filters.a_slam"
    selection = settings_from_config(cfg, "selection")
    for name in ARTICULATED:
        if name not in selection.models:
            raise ConfigError(f"selection.models: A-SLAM needs {name!r} among the models, "
                              f"got {list(selection.models)}")
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
        max_pose_sigma_m=(float("inf") if lookup(cfg, f"{key}.max_pose_sigma_m", None) is None
                          else get_float(cfg, f"{key}.max_pose_sigma_m", low=0.0, low_open=True)),
        moved_m=get_float(cfg, f"{key}.moved_m", low=0.0),
        convert=_convert_models(cfg, f"{key}.convert"),
        classify_every=get_int(cfg, f"{key}.classify_every", low=1, default=1),
        common_axis=_common_axis_options(cfg, f"{key}.common_axis"),
    )


def _convert_models(cfg: Mapping, key: str) -> tuple:
    """Articulated models to convert to (default both); ConfigError naming ``key`` otherwise."""
    value = lookup(cfg, key, list(ARTICULATED))
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) or \
            any(m not in ARTICULATED for m in value) or len(set(value)) != len(value):
        raise ConfigError(f"{key}: expected a list of distinct models from {', '.join(ARTICULATED)}, got {value!r}")
    return tuple(m for m in ARTICULATED if m in value)


def _common_axis_options(cfg: Mapping, key: str) -> dict | None:
    """Checked options of :func:`stslam.articulation.hinge_axis.estimate_hinge_axis` at ``key`` (null or absent: None)."""
    block = lookup(cfg, key, None)
    if block is None:
        return None
    if not isinstance(block, Mapping):
        raise ConfigError(f"{key}: expected hinge-axis options or null, got {block!r}")
    unknown = sorted(set(block) - set(HINGE_AXIS_DEFAULTS))
    if unknown:
        raise ConfigError(f"{key}: unknown option(s) {', '.join(map(str, unknown))}")
    return hinge_axis_options(cfg, key)


# Defaults of the hinge-axis options (stslam.articulation.hinge_axis.estimate_hinge_axis) where a block may omit them.
HINGE_AXIS_DEFAULTS = {"max_angle_deg": 10.0, "max_distance_m": 0.1, "min_tracks": 2, "scale_m": 0.02,
                       "trim_factor": 3.0}


def hinge_axis_options(cfg: Mapping, key: str, defaults: bool = True) -> dict:
    """The options of :func:`stslam.articulation.hinge_axis.estimate_hinge_axis` in the block at ``key``, checked.

    With ``defaults`` an absent option takes :data:`HINGE_AXIS_DEFAULTS`; without, every option is required.
    """
    def default(name):
        return {"default": HINGE_AXIS_DEFAULTS[name]} if defaults else {}

    return {"max_angle_deg": get_float(cfg, f"{key}.max_angle_deg", low=0.0, low_open=True, high=90.0,
                                       **default("max_angle_deg")),
            "max_distance_m": get_float(cfg, f"{key}.max_distance_m", low=0.0, low_open=True,
                                        **default("max_distance_m")),
            "min_tracks": get_int(cfg, f"{key}.min_tracks", low=2, **default("min_tracks")),
            "scale_m": get_float(cfg, f"{key}.scale_m", low=0.0, low_open=True, **default("scale_m")),
            "trim_factor": get_float(cfg, f"{key}.trim_factor", low=1.0, **default("trim_factor"))}
