"""How A-SLAM's model decisions compare with a simulated world's truth (SPEC 4, 12, 18).

Per run (:func:`selection_scores`, columns of ``metrics.csv``) and per landmark
(:func:`decision_rows`, ``decisions.csv``: the report's confusion table and
decision-time distribution).
"""

from __future__ import annotations

import numpy as np

from stslam.slam.a_slam_settings import ARTICULATED

__all__ = ["SEEN_MOVING_SIGMAS", "decision_rows", "judged_rows", "seen_moving", "selection_scores", "truly_moving"]

# A mover counts as seen moving when two of its observations were taken at true positions more than
# SEEN_MOVING_SIGMAS sensor standard deviations apart: the difference of two observations has std σ√2
# per axis (SPEC 5.2), so 5σ is 3.5 of those stds, a step no noise draw imitates; for σ = 0.04 m it is
# 0.2 m, A-SLAM's own ``moved_m``. A mover never seen moving cannot be told from a static point.
SEEN_MOVING_SIGMAS = 5.0


def seen_moving(world, observation_ids, sigma_m: float) -> np.ndarray:
    """Per landmark of ``world``, whether it was seen moving (bool (n_landmarks,), SEEN_MOVING_SIGMAS).

    ``observation_ids`` holds per frame the indices of the landmarks observed
    (:class:`~stslam.sim.simulate.SimulatedRun`); the test is on the true
    positions at those frames: their largest pairwise distance exceeds
    ``SEEN_MOVING_SIGMAS · sigma_m``.
    """
    frames: dict = {}
    for k, ids in enumerate(observation_ids):
        for i in np.asarray(ids, dtype=int):
            frames.setdefault(int(i), []).append(k)
    out = np.zeros(world.n_landmarks, dtype=bool)
    for i, ks in frames.items():
        p = np.unique(world.positions[ks, i], axis=0)
        if len(p) > 1:
            spread = np.sqrt(np.max(np.sum((p[:, None, :] - p[None, :, :]) ** 2, axis=-1)))
            out[i] = spread > SEEN_MOVING_SIGMAS * sigma_m
    return out


def truly_moving(world) -> np.ndarray:
    """bool (n_frames, n_landmarks): landmark i's true position at frame k differs from frame k − 1's (frame 0:
    False). What a perfect onset test would know (``run_a_slam``'s ``moving``; the method ``a_slam_truth_onsets``)."""
    positions = np.asarray(world.positions, dtype=float)
    out = np.zeros(positions.shape[:2], dtype=bool)
    out[1:] = np.any(positions[1:] != positions[:-1], axis=-1)
    return out


def selection_scores(track: ASlamTrack, world, moved=None) -> dict:
    """Per-run selection metrics of A-SLAM against the world's true models (SPEC 4, 12).

    ``moved`` (bool per landmark, :func:`seen_moving`; None: every mover counts
    as seen moving) says which movers were seen moving. A mover seen moving is
    right when it ends on its true model; one never seen moving is right when it
    ends static, undecided (a gated static point) or on its true model.

    Returns
    -------
    dict
        ``correct``: 1 when every moving landmark is right, else 0;
        ``moving_correct_frac``: the fraction of the movers seen moving that end
        on their true model (NaN if none was seen moving); ``selection_step``: the largest, over movers seen moving,
        of the observation index at which their true model was first chosen
        (NaN if one never was); ``static_correct_frac``: fraction of the static
        landmarks with a decision whose final model is static (NaN if none).
    """
    hits_moving, right, steps, static_hits, static_decided = [], [], [], 0, 0
    for i, truth in enumerate(world.landmarks):
        report = track.landmarks.get(i)
        model = report.model if report is not None else "undecided"
        if truth.model_name == "static":
            if model != "undecided":
                static_decided += 1
                static_hits += model == "static"
            continue
        if moved is not None and not moved[i]:
            right.append(model in ("static", "undecided", truth.model_name))
            continue
        hits_moving.append(model == truth.model_name)
        right.append(hits_moving[-1])
        hits = [step for _, step, chosen in (report.decisions if report else ()) if chosen == truth.model_name]
        steps.append(hits[0] if hits else np.nan)
    decided = [(truth.model_name, track.landmarks[i]) for i, truth in enumerate(world.landmarks)
               if i in track.landmarks]
    firsts = [(true, _first_articulated(report)) for true, report in decided]
    return {"correct": int(all(right)),
            "moving_correct_frac": float(np.mean(hits_moving)) if hits_moving else np.nan,
            "selection_step": float(np.max(steps)) if steps else np.nan,
            "static_correct_frac": static_hits / static_decided if static_decided else np.nan,
            "conversions": sum(model in ARTICULATED for _, report in decided for _, _, model in report.decisions),
            "wrong_at_conversion": sum(first is not None and first[1] != true for true, first in firsts),
            "revisions": sum(report.revisions for _, report in decided)}


def _first_articulated(report):
    """(frame, model) of the landmark's first articulated decision, or None."""
    return next(((frame, model) for frame, _, model in report.decisions if model in ARTICULATED), None)


def decision_rows(track, world, moved=None) -> list[dict]:
    """One row per landmark A-SLAM saw: ``landmark``, ``true_model``, ``seen_moving`` (:func:`seen_moving`;
    True for every mover when ``moved`` is None), ``final_model``, ``first_model`` and ``first_frame`` (its
    first articulated decision; empty if none), ``right_frame`` (first frame whose decision was its true
    model; empty if none), ``decisions``, ``revisions``, ``restarts``."""
    rows = []
    for i, truth in enumerate(world.landmarks):
        report = track.landmarks.get(i)
        if report is None:
            continue
        first = _first_articulated(report)
        right = next((frame for frame, _, model in report.decisions if model == truth.model_name), None)
        rows.append({"landmark": i, "true_model": truth.model_name,
                     "seen_moving": bool(moved[i]) if moved is not None else truth.model_name != "static",
                     "final_model": report.model, "first_model": first[1] if first else "",
                     "first_frame": first[0] if first else np.nan, "right_frame": np.nan if right is None else right,
                     "decisions": len(report.decisions), "revisions": report.revisions, "restarts": report.restarts})
    return rows


def judged_rows(decisions):
    """The rows of a ``decisions.csv`` table (:func:`decision_rows`) whose final model can be judged: the
    static points and the movers seen moving (one never seen moving cannot be told from a static point)."""
    return decisions[decisions["seen_moving"].astype(bool) | (decisions["true_model"] == "static")]
