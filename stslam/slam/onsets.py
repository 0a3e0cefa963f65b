"""A-SLAM's onset tests: static points that have begun to move, held out of the update (SPEC 6.3, 18).

A slowly starting part (a drawer's first centimetres, a door's first degrees)
passes the χ² gate frame by frame, and a point used while it moves drags the
robot. Three tests find such points among those A-SLAM holds static: a CUSUM
of each point's NIS (:func:`onsets`), a drift of its estimate from an anchor
(:func:`drifted`) and a shift shared by its latest innovations
(:func:`shifted`). Settings: :class:`~stslam.slam.a_slam_settings.ASlamParams`
(``onset_*``, ``drift_bound``, ``window_bound``).
"""

from __future__ import annotations

import numpy as np

from stslam.geometry import rotation_z
from stslam.slam.a_slam_settings import ARTICULATED, ASlamParams
from stslam.slam.core import SlamState
from stslam.slam.landmark_policy import LandmarkMark
from stslam.slam.loop import Frame

__all__ = ["DRIFT_FLOOR_M", "drift_statistics", "drifted", "innovations", "onsets", "quantile", "shifted"]

DRIFT_FLOOR_M = 0.002  # a static estimate's change below this (m) is no evidence of motion (drifted)


def onsets(state, frame: Frame, marks, skip, params: ASlamParams, t: float = 0.0) -> tuple[dict, dict | None]:
    """Static points that have begun to move (held out of this frame's update), and every static NIS.

    A CUSUM of each static point's NIS against its own estimate (3 dof, mean 3),
    g ← max(0, g + NIS − ``onset_allowance``), finds a slow start (a drawer's first
    steps each pass the χ² gate, and a point used while it slides drags the robot:
    in the kitchen this, not the models, was most of A-SLAM's NEES excess). Above
    ``onset_threshold`` the point is a suspect, held out until its NIS has stayed
    under the allowance for ``onset_quiet`` frames in a row (it rests again). Returns
    (j → whether the held-out observation would have passed the gate, j → its NIS for every
    static row j: the gate of :func:`_update` reads the same values). ``t``: the frame's time (:func:`drifted`).
    Each mark notes the frame its CUSUM last left zero (``rising``, Page's estimate of the change point;
    None while at zero) and the frame it was last flagged (``flagged``): a replay starts from the first
    (:mod:`stslam.slam.replay`).
    """
    if params.onset_allowance is None:
        return {}, None
    rows = [j for j, i in enumerate(frame.ids)
            if i in state and j not in skip and marks[i].status not in ARTICULATED]
    if not rows:
        return {}, None
    nis = state.observation_nis([frame.ids[j] for j in rows], frame.zs[rows], frame.Rs[rows])
    # The allowance grows with the frame's NIS: when even its best-fitting points have a high NIS, the
    # robot is off (or the filter's covariance too small), and that is no point's motion (settings docstring).
    values = nis.tolist()
    allowance = max(params.onset_allowance, 2.0 * quantile(values, params.onset_frame_quantile))
    held = {}
    # The drift test reads a filter's estimates (a smoother revises its past ones): EKF states only.
    drift_bound = params.drift_bound if isinstance(state, SlamState) else None
    shifts = innovations(state, frame, rows) if params.onset_windows and isinstance(state, SlamState) else None
    positions = state.landmark_positions([frame.ids[j] for j in rows]) if drift_bound is not None else None
    for i in frame.ids:  # an anchor (and an innovation window) belongs to one static life of a point
        if i in marks and marks[i].status in ARTICULATED:
            marks[i].anchor, marks[i].window = None, []
    drifts = (drift_statistics([marks[frame.ids[j]].anchor for j in rows], positions, t, params.sigma_walk)
              if drift_bound is not None else None)
    for n, (j, value) in enumerate(zip(rows, values, strict=True)):
        mark = marks[frame.ids[j]]
        previous, was_suspect = mark.onset, mark.suspect
        mark.onset = max(0.0, mark.onset + value - allowance)
        if mark.suspect:
            mark.quiet = mark.quiet + 1 if value <= allowance else 0
            mark.suspect = mark.quiet < params.onset_quiet
        elif mark.onset > params.onset_threshold or (
                drift_bound is not None and drifted(state, frame.ids[j], mark, drift_bound, t, params.sigma_walk,
                                                    positions[n], drifts[n])) or (
                shifts is not None and shifted(mark, shifts[0][n], shifts[1][n], params)):
            mark.suspect, mark.quiet, mark.anchor, mark.window = True, 0, None, []  # re-anchored where it rests again
        if mark.suspect:
            mark.onset = 0.0
            held[j] = value <= params.max_nis  # True: within the gate, held out without counting against it
        if mark.suspect and not was_suspect:
            mark.flagged = frame.k  # (its rise stays: the replay reads it)
        elif mark.onset <= 0.0:
            mark.rising = None
        elif previous <= 0.0:
            mark.rising = frame.k
    return held, dict(zip(rows, values, strict=True))


def quantile(values: list, q: float) -> float:
    """The q-quantile of ``values`` interpolated linearly between order statistics (numpy's default; at
    q = 0.5 exactly ``statistics.median``), in Python: 70x faster than numpy on a frame's few dozen."""
    ordered = sorted(values)
    position = q * (len(ordered) - 1)
    low = int(position)
    if low + 1 >= len(ordered):
        return ordered[-1]
    frac = position - low
    return (1.0 - frac) * ordered[low] + frac * ordered[low + 1]


def drifted(state, landmark_id, mark: LandmarkMark, bound: float, t: float, sigma_walk: float,
            position: tuple | None = None, statistic: float | None = None) -> bool:
    """Whether a static point's estimate m has left its anchor (m_a, P_a) by more than refinement explains.

    For a constant estimated by a linear filter, the change of the estimate between two times is
    independent of the later error, so m − m_a ~ N(0, P_a − P) while the point stays put (SPEC 6.3's
    static point; the filter's marginals m, P of :meth:`landmark_position`); its random walk (SPEC 6.3 (a),
    ``sigma_walk``) may move it by σ_walk²(t − t_a) I more. The statistic (m − m_a)ᵀC⁻¹(m − m_a), C the sum of
    the two (:func:`drift_statistics`), is compared with ``bound`` (a χ² quantile, 3 dof). The anchor is set
    at the first test of a static life and moves to the current estimate whenever the point's variance has
    halved since, so the reference sharpens as the point is refined. Catches a point the filter follows as it
    moves (a young point, whose large gain keeps the innovations, hence the NIS CUSUM, small).
    ``position``: its (m, P) when already at hand; ``statistic``: the statistic against its current anchor,
    when already computed.
    """
    m, P = state.landmark_position(landmark_id) if position is None else position
    if mark.anchor is None:
        mark.anchor = (m, P, t)
        return False
    if statistic is None:
        statistic = drift_statistics([mark.anchor], [(m, P)], t, sigma_walk)[0]
    if statistic > bound:
        return True
    if np.trace(P) < 0.5 * np.trace(mark.anchor[1]):
        mark.anchor = (m, P, t)
    return False


def drift_statistics(anchors: list, positions: list, t: float, sigma_walk: float) -> list:
    """:func:`drifted`'s statistic (m − m_a)ᵀC⁻¹(m − m_a) of each point, C = P_a − P + σ_walk²(t − t_a) I, floored
    at (``DRIFT_FLOOR_M``)² per eigendirection of P_a − P; None where the anchor is None. ``anchors``: (m_a, P_a,
    t_a) or None each; ``positions``: (m, P) each. One stacked eigendecomposition for all (each point's numbers
    are those of its own)."""
    rows = [n for n, anchor in enumerate(anchors) if anchor is not None]
    out = [None] * len(anchors)
    if not rows:
        return out
    m_a = np.array([anchors[n][0] for n in rows])
    D = np.array([anchors[n][1] for n in rows]) - np.array([positions[n][1] for n in rows])
    values, vectors = np.linalg.eigh(0.5 * (D + D.transpose(0, 2, 1)))
    d = (vectors.transpose(0, 2, 1) @ (np.array([positions[n][0] for n in rows]) - m_a)[:, :, None])[:, :, 0]
    walked = sigma_walk ** 2 * (t - np.array([anchors[n][2] for n in rows]))
    stats = np.sum(d ** 2 / np.maximum(values + walked[:, None], DRIFT_FLOOR_M ** 2), axis=1)
    for n, value in zip(rows, stats.tolist(), strict=True):
        out[n] = value
    return out


def innovations(state: SlamState, frame: Frame, rows: list) -> tuple[np.ndarray, np.ndarray]:
    """World-axis innovations ν (k, 3) and their covariances S (k, 3, 3) of the static ``rows`` of ``frame``
    against the state before its update (SPEC 5.3: y = z − h(x), S = H P Hᵀ + R, turned by R(θ))."""
    ids = [frame.ids[j] for j in rows]
    rot = rotation_z(state.pose[2])
    y = frame.zs[rows] - np.array([row[0] for row in state.predict_observations(ids)])
    S = np.array(state.innovation_covariances(ids, frame.Rs[rows]))
    return y @ rot.T, rot @ S @ rot.T


def shifted(mark: LandmarkMark, y, S, params: ASlamParams) -> bool:
    """Whether a static point's recent innovations share a mean: a windowed GLR test of a shift.

    While a point stays put (SPEC 6.3's static point), a consistent filter's innovations are white,
    y_k ~ N(0, S_k): over the last w sightings (Σy)ᵀ(ΣS)⁻¹(Σy) ~ χ²₃. A point that moved and rests elsewhere,
    or whose estimate averaged a stretch of motion, leaves a mean b in every innovation: non-centrality
    w bᵀS⁻¹b grows with w although each NIS stays small (the CUSUM's allowance hides a bias under ~2σ).
    Each window length w of ``onset_windows`` is tested against ``window_bound`` (χ²₃ at
    1 − (1 − ``onset_window_probability``)/#windows: Bonferroni over the lengths). The window holds one
    static life (cleared at a flag, a restart, a conversion).
    """
    mark.window = (mark.window + [(y, S)])[-max(params.onset_windows):]
    sum_y, sum_S = np.zeros(3), np.zeros((3, 3))
    n = 0
    for w in sorted(params.onset_windows):
        if w > len(mark.window):
            break
        for y_k, S_k in mark.window[len(mark.window) - w:len(mark.window) - n]:
            sum_y += y_k
            sum_S += S_k
        n = w
        if float(sum_y @ np.linalg.solve(sum_S, sum_y)) > params.window_bound:
            return True
    return False
