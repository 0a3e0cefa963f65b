"""Run a filter of :mod:`stslam.slam.filters` with the iSAM2 back end (SPEC 14).

The filter's own policy (the baselines' :class:`~stslam.slam.loop.BlockPolicy`,
A-SLAM's selection and conversion) drives :func:`stslam.slam.loop.run_slam`
exactly as under the EKF; only the state is a :class:`~stslam.graph.state.GraphState`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from stslam.graph.bodies import GraphBodyState
from stslam.graph.state import GraphState
from stslam.slam.bodies.policy import BodyLandmarkPolicy
from stslam.slam.filters import run_filter
from stslam.slam.inputs import as_inputs
from stslam.slam.loop import run_slam

def gtsam_problem() -> str | None:
    """Why gtsam cannot serve the back end (not installed, or a version outside 4.3.x), or None."""
    try:
        import gtsam  # noqa: F401
    except ImportError:
        return "not installed"
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = version("gtsam")
    except PackageNotFoundError:  # importable, but not an installed distribution: trust it
        return None
    numbers = tuple(int(p) for p in found.split(".")[:2] if p.isdigit())
    return None if (4, 3) <= numbers < (4, 4) else f"found {found}"


@dataclass(frozen=True)
class GraphTrack:
    """A filter's run under iSAM2: the smoothed trajectory in FilterTrack's fields, the causal one beside it.

    Attributes
    ----------
    poses_xytheta, pose_covs : numpy.ndarray, shapes (n, 3), (n, 3, 3)
        The final smoothed trajectory and its marginal covariances (iSAM2).
    n_rejected : int
        Observations the gates rejected.
    landmarks : dict
        A-SLAM's landmark reports (:class:`stslam.slam.a_slam.LandmarkReport`); empty for the baselines.
    online_poses_xytheta, online_pose_covs : numpy.ndarray, shapes (n, 3), (n, 3, 3)
        The causal estimate: each pose and its marginal as estimated at its own frame.
    qr_fallbacks : int
        Times iSAM2 under Cholesky found the system indeterminate and was rebuilt under QR
        (:class:`~stslam.graph.solver.FullSolver`; at most one a run, which stays on QR).
    """

    poses_xytheta: np.ndarray
    pose_covs: np.ndarray
    n_rejected: int
    landmarks: dict
    online_poses_xytheta: np.ndarray
    online_pose_covs: np.ndarray
    qr_fallbacks: int = 0


def run_filter_isam2(spec, inputs, settings, observer: Callable | None = None) -> GraphTrack:
    """Run ``spec`` (:class:`~stslam.slam.filters.FilterSpec`) over one sequence on a GraphState with ``settings``
    (over the window ``settings.lag_s`` only when ``spec.name`` is in ``settings.windowed``)."""
    inputs = as_inputs(inputs)
    if spec.name not in settings.windowed:
        settings = replace(settings, lag_s=None)
    policy = spec.policy_for(inputs)
    rules = getattr(policy, "landmarks", None)  # A-SLAM's LandmarkPolicy: its structures are fitted
    if rules is None:  # the oracle's structures are the truth: nothing to correct
        settings = replace(settings, structure="fixed")
    # SPEC 13: A-SLAM with bodies holds them in the graph as in the EKF state.
    make = GraphBodyState if isinstance(rules, BodyLandmarkPolicy) else GraphState
    state = make(inputs.initial_pose_xytheta, np.zeros((3, 3)), spec.motion_order, settings)
    if settings.structure == "variable" and rules is not None:
        # κ inflates R for the error of a structure held fixed; δ is that error, estimated (solver.Isam2Settings).
        rules.params = replace(rules.params, structure_inflation=0.0)
    track = run_slam(inputs, policy, spec.motion_order, spec.update_iterations, observer, state,
                     settings.observe_every)
    poses, covs = state.smoothed()
    return GraphTrack(poses, covs, track.n_rejected, dict(getattr(track, "landmarks", {})),
                      track.poses_xytheta, track.pose_covs, state._solver.fallbacks)


def backend_runner(backend: str, settings=None) -> Callable:
    """``run(spec, inputs, observer=None)`` of a back end: the EKF's :func:`~stslam.slam.filters.run_filter`, or iSAM2's
    with ``settings`` (:class:`~stslam.graph.state.Isam2Settings`)."""
    if backend == "ekf":
        return run_filter
    if backend != "isam2":
        raise ValueError(f"backend: expected ekf or isam2, got {backend!r}")
    return lambda spec, inputs, observer=None: run_filter_isam2(spec, inputs, settings, observer)


def online_scores(track, score) -> dict:
    """``ate_online_m``, ``rpe_online_m``, ``nees_online`` of a GraphTrack's causal estimate, and its ``qr_fallbacks``
    ({} for EKF tracks).

    ``score(poses (n, 3), covs (n, 3, 3))`` is the experiment's own scoring, returning
    ``ate_m``, ``rpe_m`` and ``nees``.
    """
    if not isinstance(track, GraphTrack):
        return {}
    scores = score(track.online_poses_xytheta, track.online_pose_covs)
    return {"ate_online_m": scores["ate_m"], "rpe_online_m": scores["rpe_m"], "nees_online": scores["nees"],
            "qr_fallbacks": track.qr_fallbacks}
