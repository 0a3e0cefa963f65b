"""Which joint moved a rigid part, from its pose track: noise, model choice and a consistency check (SPEC 17, 4).

Noise (:func:`estimate_pose_noise`). At 30 Hz a door or drawer moves
smoothly, so the second difference of consecutive poses, d_t = x_{t+1} − 2 x_t
+ x_{t−1}, is mostly noise: Var d = 6 σ² for white noise of variance σ². Its
covariance is estimated robustly (trimmed at the 99% χ² point of a first,
median-absolute-deviation scale, then corrected for the trimming) for the
position and for the orientation increments log(R_{t+1} R_tᵀ).

Choice (:func:`decide_model`). Every model of :mod:`stslam.articulation.pose_joint`
is fitted; each frame's whitened χ² is capped at ``frame_chi2_cap`` (a pose the
flip choice got wrong, a corner mis-detected, costs no more than that), and
the model with the smallest BIC = Σ_t min(χ²_t, cap) + k ln(6 n) wins, k its
parameter count (SPEC 4's selection, as a batch decision on the whole track).
The frame-to-frame noise misses the errors that hold while the view holds (a
small marker's pose errs by a bias that changes slowly), so against it every
model's χ² is large, many frames reach the cap, and a still part (6 parameters)
looks cheap; the BIC is therefore computed again with the noise the best
moving model leaves in its residuals, which counts those errors.
Only a part whose centre travels ``min_travel_m`` (robust extent) can be
prismatic, and only one that turns ``min_turn_deg`` (robust extent of θ) can be
revolute, each also at least ``min_extent_sigmas`` times the frame-to-frame
noise along the line or about the axis (a drawer's marker whose orientation drifts by a degree as it crosses
the image is no door with a 20 m radius); a part that does neither is static.

The chosen model's final fit (:func:`final_fit`). Second differences see the
noise that changes from frame to frame; a small marker's pose also errs by a
bias that holds while the view holds (the same pixels give the same error).
The chosen model is therefore refitted with the noise taken from its own
residuals (robust covariance, as above), and the poses whose χ² then exceeds
the cap are left out of the last fit.

When (:func:`decision_frame`). The same choice (closed-form fits) on the first
k poses, at checkpoints: the decision counts from the first checkpoint after
which every prefix gives the final model.

Consistency (:func:`joint_consistency`). A joint explains the whole pose, not
only the centre; a camera that moved during a video without a reference
marker leaves residuals no joint explains. The chosen fit's RMS residuals
(m, deg) over the frames it keeps are compared with ``max_residual_m`` and
``max_residual_deg``, and with ``max_noise_ratio`` times the frame-to-frame
noise (both must be exceeded); a revolute hinge through the camera itself (within
``min_hinge_to_camera_m`` of the frame's origin) is the camera turning, not a
door.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2 as chi2_distribution

from stslam.articulation.pose_joint import MODELS, PoseJointFit, PoseNoise, fit_pose_model, rotation_vectors
from stslam.checks import check_fields, check_int

TRIM_PROBABILITY = 0.99


@dataclass(frozen=True)
class MotionThresholds:
    """What counts as motion (module docstring, Choice): a centre's travel ``min_travel_m`` (m) for prismatic,
    a turn ``min_turn_deg`` (deg) for revolute, each also ``min_extent_sigmas`` times the frame-to-frame noise."""

    min_travel_m: float = 0.05
    min_turn_deg: float = 10.0
    min_extent_sigmas: float = 6.0


@dataclass(frozen=True)
class ChoiceSettings:
    """The choice (module docstring): the cap on a frame's χ² and the floors of the noise (σ per axis; m, deg)."""

    frame_chi2_cap: float = 30.0
    min_noise_m: float = 0.0005
    min_noise_deg: float = 0.1


@dataclass(frozen=True)
class ConsistencyThresholds:
    """The consistency check (module docstring): RMS residuals ``max_residual_m`` (m) and ``max_residual_deg``
    (deg), each only when also ``max_noise_ratio`` times the frame-to-frame noise; a hinge within
    ``min_hinge_to_camera_m`` (m) of the camera is the camera turning."""

    max_residual_m: float = 0.03
    max_residual_deg: float = 5.0
    max_noise_ratio: float = 5.0
    min_hinge_to_camera_m: float = 0.15


@dataclass(frozen=True)
class PoseDecisionSettings:
    """Settings of each step (module docstring; config ``decision.*``): what counts as motion, the choice, the
    consistency check, and how many prefixes :func:`decision_frame` tries (``checkpoints``). Checked here,
    where they are used together; a wrong value is named by its path (``consistency.max_residual_m``)."""

    motion: MotionThresholds = MotionThresholds()
    choice: ChoiceSettings = ChoiceSettings()
    consistency: ConsistencyThresholds = ConsistencyThresholds()
    checkpoints: int = 40

    def __post_init__(self):
        intervals = {"motion.min_travel_m": "[0, inf)", "motion.min_turn_deg": "[0, inf)",
                     "motion.min_extent_sigmas": "[0, inf)", "choice.frame_chi2_cap": "(0, inf)",
                     "choice.min_noise_m": "(0, inf)", "choice.min_noise_deg": "(0, inf)",
                     "consistency.max_residual_m": "(0, inf)", "consistency.max_residual_deg": "(0, inf)",
                     "consistency.max_noise_ratio": "(0, inf)", "consistency.min_hinge_to_camera_m": "[0, inf)"}
        check_fields(self, **intervals)
        check_int("checkpoints", self.checkpoints, low=1, high=10000)


def _robust_covariance(d: np.ndarray) -> np.ndarray:
    """Covariance (3, 3) of rows d (m, 3) around zero, trimmed at the 99% χ²₃ point (module docstring)."""
    scale = 1.4826 * np.median(np.abs(d - np.median(d, axis=0)), axis=0)
    scale = np.maximum(scale, 1e-12)
    m2 = np.sum((d / scale) ** 2, axis=1)
    limit = chi2_distribution.ppf(TRIM_PROBABILITY, 3)
    kept = d[m2 <= limit]
    if kept.shape[0] < 4:
        return np.diag(scale**2)
    # E[d dᵀ | d within the ellipsoid] = Σ P(χ²₅ ≤ q) / P(χ²₃ ≤ q) for Gaussian d
    shrink = chi2_distribution.cdf(limit, 5) / chi2_distribution.cdf(limit, 3)
    return kept.T @ kept / kept.shape[0] / shrink


def _noise_with_floor(position_cov, rotation_cov, min_noise_m: float, min_noise_deg: float) -> PoseNoise:
    return PoseNoise(position_cov + min_noise_m**2 * np.eye(3), rotation_cov + np.radians(min_noise_deg) ** 2 * np.eye(3))


def estimate_pose_noise(p, R, frames, min_noise_m: float = 0.0005, min_noise_deg: float = 0.1) -> PoseNoise:
    """Per-pose noise from second differences of consecutive frames (module docstring); floors ``min_noise_m``
    and ``min_noise_deg`` (σ per axis) keep a noise-free (rendered) track from weighing infinitely."""
    p = np.asarray(p, dtype=float)
    frames = np.asarray(frames, dtype=int)
    triple = np.flatnonzero((np.diff(frames)[1:] == 1) & (np.diff(frames)[:-1] == 1)) + 1
    if triple.size < 8:  # too few to tell: a loose guess (σ 10× the floor)
        return _noise_with_floor(np.zeros((3, 3)), np.zeros((3, 3)), 10 * min_noise_m, 10 * min_noise_deg)
    d_p = p[triple + 1] - 2 * p[triple] + p[triple - 1]
    step = rotation_vectors(np.einsum("nij,nkj->nik", R[1:], R[:-1]))  # log(R_{t+1} R_tᵀ), t = 0 … n − 2
    d_r = step[triple] - step[triple - 1]
    return _noise_with_floor(_robust_covariance(d_p) / 6.0, _robust_covariance(d_r) / 6.0, min_noise_m,
                             min_noise_deg)


def robust_extent(values) -> float:
    """Spread of values (n,) between their 2nd and 98th percentiles (a few outliers do not count)."""
    v = np.asarray(values, dtype=float)
    return float(np.percentile(v, 98) - np.percentile(v, 2)) if v.size else 0.0


def motion_range(q, window: int = 7) -> float:
    """Range (max − min) of a motion variable q (n,) after a running median over ``window`` poses: the range of
    the raw values would add the noise's extremes at both ends (measured +1.2° on a 70° door with 1° noise)."""
    q = np.asarray(q, dtype=float)
    if q.size < window:
        return float(np.ptp(q)) if q.size else 0.0
    half = window // 2
    padded = np.concatenate([np.full(half, q[0]), q, np.full(half, q[-1])])
    smooth = np.median(np.lib.stride_tricks.sliding_window_view(padded, window), axis=1)
    return float(np.ptp(smooth))


def travel_m(p) -> float:
    """Robust extent (m) of positions (n, 3) along their principal direction."""
    p = np.asarray(p, dtype=float)
    centred = p - np.median(p, axis=0)
    direction = np.linalg.svd(centred, full_matrices=False)[2][0]
    return robust_extent(centred @ direction)


def bic(fit: PoseJointFit, cap: float) -> float:
    """Σ_t min(χ²_t, cap) + k ln(6 n) (module docstring)."""
    n = fit.frame_chi2.shape[0]
    return float(np.sum(np.minimum(fit.frame_chi2, cap)) + fit.n_parameters * np.log(6.0 * n))


@dataclass(frozen=True)
class PoseDecision:
    """The model chosen, every model's fit and BIC, and the centre's travel (m) and the turn (deg)."""

    model: str
    fits: dict
    bic: dict
    travel_m: float
    turn_deg: float


def residual_noise(fit: PoseJointFit, settings: PoseDecisionSettings = PoseDecisionSettings()) -> PoseNoise:
    """The noise a fit leaves: robust covariances of its position and orientation residuals, with the floors."""
    return _noise_with_floor(_robust_covariance(fit.position_residuals), _robust_covariance(fit.rotation_residuals),
                             settings.choice.min_noise_m, settings.choice.min_noise_deg)


def _scored(p, R, noise: PoseNoise, settings: PoseDecisionSettings, refine: bool) -> tuple[dict, dict]:
    fits = {m: fit_pose_model(m, p, R, noise, refine=refine) for m in MODELS}
    return fits, {m: bic(f, settings.choice.frame_chi2_cap) for m, f in fits.items()}


def decide_model(p, R, noise: PoseNoise, settings: PoseDecisionSettings = PoseDecisionSettings(),
                 refine: bool = True) -> PoseDecision:
    """The model of a pose track (module docstring); ``refine=False`` uses closed-form revolute fits only."""
    fits, scores = _scored(p, R, noise, settings, refine)
    travel = travel_m(p)
    turn = float(np.degrees(robust_extent(fits["revolute"].q)))
    k = settings.motion.min_extent_sigmas  # pure noise spans ~4.1 σ between its 2nd and 98th percentiles
    line, axis = fits["prismatic"].axis, fits["revolute"].axis
    sigma_travel = float(np.sqrt(line @ noise.position_cov @ line))
    sigma_turn_deg = float(np.degrees(np.sqrt(axis @ noise.rotation_cov @ axis)))
    moving = [m for m, ok in (("prismatic", travel >= max(settings.motion.min_travel_m, k * sigma_travel)),
                              ("revolute", turn >= max(settings.motion.min_turn_deg, k * sigma_turn_deg))) if ok]
    if moving:  # the BIC again, with the noise the best moving joint leaves (module docstring)
        fits, scores = _scored(p, R, residual_noise(fits[min(moving, key=scores.get)], settings), settings, refine)
    model = min(moving, key=lambda m: scores[m]) if moving else "static"
    model = model if scores[model] < scores["static"] else "static"
    return PoseDecision(model, fits, scores, travel, turn)


def final_fit(model: str, p, R, noise: PoseNoise, settings: PoseDecisionSettings = PoseDecisionSettings()
              ) -> tuple[PoseJointFit, np.ndarray, PoseNoise]:
    """The chosen model refitted with the noise of its own residuals (module docstring): the fit on the kept
    poses, the kept poses (n,) bool, and that noise."""
    p = np.asarray(p, dtype=float)
    R = np.asarray(R, dtype=float)
    noise = residual_noise(fit_pose_model(model, p, R, noise), settings)
    again = fit_pose_model(model, p, R, noise)
    kept = again.frame_chi2 <= settings.choice.frame_chi2_cap
    if kept.all() or kept.sum() < 8:
        return again, np.ones(p.shape[0], dtype=bool), noise
    return fit_pose_model(model, p[kept], R[kept], noise), kept, noise


def decision_frame(p, R, frames, noise: PoseNoise, final_model: str,
                   settings: PoseDecisionSettings = PoseDecisionSettings()) -> int:
    """Frame (from ``frames`` (n,)) from which every prefix of the track decides ``final_model`` (module
    docstring; closed-form fits on the prefixes; the whole track's decision is the final one by definition, so
    at worst the last frame)."""
    n = len(frames)
    ends = np.unique(np.linspace(min(8, n), n, settings.checkpoints + 1).astype(int))[:-1]
    decided = int(frames[-1])
    for end in ends[::-1]:  # from the whole track back: the last prefix that disagrees ends the run
        if decide_model(p[:end], R[:end], noise, settings, refine=False).model != final_model:
            break
        decided = int(frames[end - 1])
    return decided


@dataclass(frozen=True)
class Consistency:
    """Whether a joint explains the track: RMS residuals (m, deg) over the kept frames, the kept frames
    (n,) bool, the hinge's distance from the frame's origin (m; revolute, else None), and the problems found."""

    residual_rms_m: float
    residual_rms_deg: float
    kept: np.ndarray
    hinge_to_origin_m: float | None
    problems: tuple


def joint_consistency(fit: PoseJointFit, settings: PoseDecisionSettings = PoseDecisionSettings(),
                      origin_is_camera: bool = True, noise: PoseNoise | None = None) -> Consistency:
    """Check of the chosen fit (module docstring); frames with χ² above the cap are left out of the RMS.

    With ``noise`` (the frame-to-frame noise of :func:`estimate_pose_noise`), a residual counts as too large
    only if it is also more than ``max_noise_ratio`` times that noise: a distant, noisy marker strays far
    from its joint from frame to frame, a camera that moved strays far beyond its frame-to-frame noise.
    """
    kept = fit.frame_chi2 <= settings.choice.frame_chi2_cap
    if kept.sum() < 3:
        kept = np.ones_like(kept)
    r_p, r_R = fit.position_residuals[kept], fit.rotation_residuals[kept]
    rms_m = float(np.sqrt(np.mean(np.sum(r_p**2, axis=1))))
    rms_deg = float(np.degrees(np.sqrt(np.mean(np.sum(r_R**2, axis=1)))))
    ratio_p = ratio_r = np.inf
    if noise is not None:
        W_p, W_r = noise.whiteners()
        ratio_p = float(np.sqrt(np.mean(np.sum((r_p @ W_p) ** 2, axis=1)) / 3.0))
        ratio_r = float(np.sqrt(np.mean(np.sum((r_R @ W_r) ** 2, axis=1)) / 3.0))
    problems, limits = [], settings.consistency
    if rms_m > limits.max_residual_m and ratio_p > limits.max_noise_ratio:
        problems.append(f"the marker's centre strays {100 * rms_m:.1f} cm RMS from the best {fit.model} joint "
                        f"(at most {100 * limits.max_residual_m:.1f} cm expected)")
    if rms_deg > limits.max_residual_deg and ratio_r > limits.max_noise_ratio:
        problems.append(f"its orientation strays {rms_deg:.1f}° RMS from it (at most {limits.max_residual_deg:.1f}° "
                        "expected)")
    if kept.mean() < 0.5:
        problems.append(f"only {kept.mean():.0%} of the poses fit it")
    distance = None
    if fit.model == "revolute":
        distance = float(np.linalg.norm(fit.point - (fit.point @ fit.axis) * fit.axis))
        if origin_is_camera and distance < limits.min_hinge_to_camera_m:
            problems.append(f"the fitted hinge passes {100 * distance:.0f} cm from the camera: the camera turned, "
                            "not the marker")
    return Consistency(rms_m, rms_deg, kept, distance, tuple(problems))
