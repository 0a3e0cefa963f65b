"""The SLAM filters compared in ``dynamic_slam`` and how one is run over a simulated sequence (SPEC 6).

A filter is the shared core (:class:`~stslam.slam.core.SlamState`) run by the
frame loop of :mod:`stslam.slam.loop`, plus a rule that gives every landmark
its block at first sight and an optional innovation gate (its policy):

=======================  ==================================================  ==========
name                     landmark block                                      gate
=======================  ==================================================  ==========
``ekf_slam``             static point, random walk σ_walk  (SPEC 6.1)        none
``dyn_slam``             constant-velocity point, σ_acc   (SPEC 6.2)         none
``ekf_slam_gated``       static point, random walk σ_walk  (SPEC 6.5)        χ²₃ 99%
``a_slam``               static point until selection chooses a model,       χ²₃ 99%
                         then that model's motion state (SPEC 4, 6.3;
                         :mod:`stslam.slam.a_slam`)
``a_slam_truth_onsets``  ``a_slam`` (its settings), told by the simulation   χ²₃ 99%
                         which of its observations were taken while their
                         point moved: a bound for the onset tests (SPEC 18),
                         not an estimator
``oracle``               true model + structure, order-k motion state        none
                         (σ_η per unit: m for static/prismatic, rad for
                         revolute, optionally its own for static points;
                         SPEC 2, 3, 11)
=======================  ==================================================  ==========

Each filter's parameters are a settings dataclass (:data:`FILTER_PARAMS`; from
the config's ``filters.<name>``, tuned per world in ``conf/tuning/``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import partial

from scipy.stats import chi2

from stslam.slam.a_slam import ASlamFramePolicy
from stslam.slam.a_slam_settings import ArticulatedNoise, ASlamParams
from stslam.slam.blocks import ArticulatedBlock, ConstantVelocityPointBlock, StaticPointBlock
from stslam.slam.decision_scores import truly_moving
from stslam.slam.inputs import as_inputs
from stslam.slam.loop import BlockPolicy, FilterTrack, run_slam
from stslam.sim.worlds import World

FILTER_NAMES = ("ekf_slam", "dyn_slam", "ekf_slam_gated", "a_slam", "a_slam_truth_onsets", "oracle")


@dataclass(frozen=True)
class FilterSpec:
    """How a filter is run.

    Attributes
    ----------
    name : str
    policy_for : callable
        SlamInputs → the filter's :class:`~stslam.slam.loop.FramePolicy` for one run of
        :func:`~stslam.slam.loop.run_slam` (the baselines' :class:`~stslam.slam.loop.BlockPolicy`,
        A-SLAM's :class:`~stslam.slam.a_slam.ASlamFramePolicy`).
    motion_order : int
        1 or 2, how the control noise enters the prediction (:class:`~stslam.slam.core.SlamState`).
    update_iterations : int
        1 (EKF) or more (iterated EKF) linearisations per update (:class:`~stslam.slam.core.SlamState`).
    """

    name: str
    policy_for: Callable
    motion_order: int = 2
    update_iterations: int = 1


@dataclass(frozen=True)
class EkfSlamParams:
    """``ekf_slam``: landmarks are static points with random walk ``sigma_walk`` (m/√s; SPEC 6.1)."""

    sigma_walk: float


@dataclass(frozen=True)
class GatedEkfSlamParams:
    """``ekf_slam_gated``: ``ekf_slam`` whose observations pass a χ² (3 dof) gate of probability
    ``gate_probability`` (SPEC 6.5)."""

    sigma_walk: float
    gate_probability: float = 0.99


@dataclass(frozen=True)
class DynSlamParams:
    """``dyn_slam``: constant-velocity points, white acceleration ``sigma_acc`` (m/s²), prior velocity std
    ``sigma_v0`` (m/s; SPEC 6.2)."""

    sigma_acc: float
    sigma_v0: float


@dataclass(frozen=True)
class OracleParams(ArticulatedNoise):
    """``oracle``: each landmark's true model and structure with an order-``order`` motion state (SPEC 2, 3).

    ``sigma_eta_m``/``sigma_eta_rad``: process noise of static/prismatic q (m/s^(k+1)) and revolute φ
    (rad/s^(k+1)); ``sigma_eta_static_m``: that of static q if given (the oracle knows which points
    are static; None: ``sigma_eta_m``); ``sigma_rate0_m``/``sigma_rate0_rad``: prior std of q̇ at
    first sight (m/s, rad/s). The articulated noise is A-SLAM's (:class:`ArticulatedNoise`), with defaults
    of the rates' std of its own.
    """

    sigma_rate0_m: float = 0.05
    sigma_rate0_rad: float = 1.0
    order: int = 1
    sigma_eta_static_m: float | None = None

    def sigma_eta(self, model_name: str) -> float:
        """σ_η of a landmark of true model ``model_name``."""
        if model_name == "static" and self.sigma_eta_static_m is not None:
            return self.sigma_eta_static_m
        return super().sigma_eta(model_name)


FILTER_PARAMS = {"ekf_slam": EkfSlamParams, "dyn_slam": DynSlamParams, "ekf_slam_gated": GatedEkfSlamParams,
                 "a_slam": ASlamParams, "a_slam_truth_onsets": ASlamParams, "oracle": OracleParams}


def make_filter(name: str, params, world: World, motion_order: int = 2,
                iterations: int = 1) -> FilterSpec:
    """The :class:`FilterSpec` of ``name`` with ``params``, an instance of ``FILTER_PARAMS[name]``.

    ``motion_order`` (1 or 2) is how every filter's prediction propagates the
    control noise, ``iterations`` how many times each update is linearised
    (:class:`~stslam.slam.core.SlamState`). Raises ValueError for an unknown
    ``name`` or a ``motion_order`` or ``iterations`` out of range.
    """
    if motion_order not in (1, 2):
        raise ValueError(f"motion_order: expected 1 or 2, got {motion_order!r}")
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 1:
        raise ValueError(f"iterations: expected an integer ≥ 1, got {iterations!r}")
    return replace(_filter_spec(name, params, world), motion_order=motion_order, update_iterations=iterations)


def _filter_spec(name: str, params, world: World) -> FilterSpec:
    if name == "ekf_slam":
        return _block_spec(name, StaticPointBlock(params.sigma_walk))
    if name == "ekf_slam_gated":
        gate = float(chi2.ppf(params.gate_probability, 3))
        return _block_spec(name, StaticPointBlock(params.sigma_walk), gate)
    if name == "dyn_slam":
        return _block_spec(name, ConstantVelocityPointBlock(params.sigma_acc, params.sigma_v0))
    if name == "oracle":
        blocks = []
        for truth in world.landmarks:
            blocks.append(ArticulatedBlock(truth.model, truth.structure, params.order,
                                           params.sigma_eta(truth.model_name), params.sigma_rate0(truth.model_name)))
        policy = BlockPolicy(blocks.__getitem__)
        return FilterSpec(name, lambda inputs: policy)
    if name == "a_slam":
        return FilterSpec(name, partial(ASlamFramePolicy, params))
    if name == "a_slam_truth_onsets":  # SPEC 18: what a perfect onset test would give A-SLAM (a bound)
        return FilterSpec(name, partial(ASlamFramePolicy, params, moving=truly_moving(world)))
    raise ValueError(f"name: expected one of {', '.join(FILTER_NAMES)}; got {name!r}")


def _block_spec(name: str, block, max_nis: float | None = None) -> FilterSpec:
    """A baseline: the same ``block`` for every landmark, gated on ``max_nis`` if given."""
    policy = BlockPolicy(lambda i: block, max_nis)
    return FilterSpec(name, lambda inputs: policy)


def run_filter(spec: FilterSpec, inputs, observer: Callable | None = None) -> FilterTrack:
    """Run a filter over one sequence (:class:`~stslam.slam.inputs.SlamInputs` or a SimulatedRun).

    The loop of :func:`~stslam.slam.loop.run_slam` with the filter's policy
    (for the baselines: each frame's observations of landmarks already in the
    state update it jointly, each with its own R and, if the filter gates, on
    its own NIS; new landmarks are added with the filter's block, in the
    frame's order). ``observer(k, state)``, if given, is called after each
    frame (diagnostics; it must not change the state). A-SLAM returns an
    :class:`~stslam.slam.a_slam.ASlamTrack`, which has FilterTrack's fields.
    """
    inputs = as_inputs(inputs)
    return run_slam(inputs, spec.policy_for(inputs), spec.motion_order, spec.update_iterations, observer)
