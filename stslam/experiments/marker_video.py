"""A marker video in, the joint out (SPEC 17): ``python experiments/run.py +exp=marker_video video=… calib=… …``.

Steps: the calibration (:mod:`stslam.io.camera_file`, K scaled if the frames
are the calibrated ones resized); every frame decoded once
(:mod:`stslam.io.video`), its markers detected (:mod:`stslam.markers.detect`)
and its JPEG kept for scene.mcap; the marker's pose track with IPPE's flips
avoided (:mod:`stslam.markers.track`), relative to ``reference_id`` when given;
the per-pose noise, the model and the decision frame
(:mod:`stslam.articulation.pose_decision`), the chosen model refitted on the
poses it explains; a joint that does not explain the track (a camera that
moved without a reference) is refused with one error line (or, with
``not_a_joint=warn``, written with ``"consistent": false`` and its warnings).
The SPEC 4 selector (``selection`` settings) classifies the centre alone as a
second opinion (``selector_model``, ``selector_frame`` in metrics.csv).
``posed`` counts the frames with a pose (the marker, and the reference when
given, detected and posed); ``left_out`` those of them the final fit did not
use (χ² above the cap: a blurred or mis-detected corner).

Files beside the SPEC 12 ones: ``articulation.json`` (model, frames, posed,
axis, point, angle_range_deg or travel_m, residual_rms_m, decided_at_frame,
and how it came about), ``track.csv`` (SPEC 10, 7 columns x, y, z, qx, qy, qz,
qw, each row's frame number as a comment) and ``scene.mcap``
(:mod:`stslam.io.marker_scene`). metrics.csv has one row (method
``marker_video``).
"""

from __future__ import annotations

import json
import os

import cv2
import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from stslam.articulation.pose_decision import (decide_model, decision_frame, estimate_pose_noise, final_fit,
                                               joint_consistency, motion_range)
from stslam.config.markers import marker_video_from_config
from stslam.config.readers import get_int, lookup
from stslam.config.selection import selection_from_config
from stslam.errors import InputFileError, StslamError
from stslam.experiments.classify_tracks import classify_track
from stslam.io import mcap_topics as mt
from stslam.io.camera_file import read_camera_calibration, scaled_to
from stslam.io.marker_scene import MarkerJoint, MarkerSceneFrame, marker_scene_bytes
from stslam.io.track_files import PointTrack, format_track
from stslam.io.video import VideoFrames
from stslam.markers.detect import MarkerDetector
from stslam.markers.pose import marker_object_points, project_points
from stslam.markers.track import most_seen_id, pose_track
from stslam.output import ExperimentOutput
from stslam.progress import progress

MIN_POSES = 8  # the second differences of the noise estimate need a few consecutive poses
AXIS_SAMPLES = 25


def _read_frames(settings, calibration, show: bool):
    """Detections per frame, JPEG bytes per frame, the calibration of the frames' size, and their rate."""
    os.environ.setdefault("OPENCV_FFMPEG_LOGLEVEL", "-8")  # FFmpeg's own lines would precede our one error line
    video = VideoFrames(settings.video)
    detections, jpegs, size, detector = [], [], None, None
    wanted = {i for i in (settings.marker_id, settings.reference_id) if i is not None}
    for frame in progress(video, "marker_video frames", total=video.info.frame_count or None, enabled=show):
        if detector is None:  # the first frame's size, whatever the container claims
            size = (frame.shape[1], frame.shape[0])
            calibration = scaled_to(calibration, *size)
            detector = MarkerDetector(settings.detection, calibration.K, calibration.D)
        if (frame.shape[1], frame.shape[0]) != size:
            raise InputFileError(settings.video, f"frame {len(jpegs)} is {frame.shape[1]} × {frame.shape[0]} px, "
                                                 f"the first {size[0]} × {size[1]}; expected one frame size")
        detections.append(detector.detect(frame, wanted))
        if settings.marker_id is None:  # not named: the markers seen so far are the wanted ones
            wanted |= set(detections[-1])
        jpegs.append(cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, settings.jpeg_quality])[1].tobytes())
    return detections, jpegs, calibration, size, video.info.fps


def _marker_id(settings, detections) -> int:
    seen = sorted({i for found in detections for i in found})
    dictionary = settings.detection.dictionary
    if settings.reference_id is not None and settings.reference_id not in seen:
        raise InputFileError(settings.video, f"reference_id {settings.reference_id} is in none of its "
                                             f"{len(detections)} frames; {dictionary} markers found: {seen or 'none'}")
    if settings.marker_id is None:
        chosen = most_seen_id(detections, exclude=settings.reference_id)
        if chosen is None:
            raise InputFileError(settings.video, f"no {dictionary} marker found in any of its {len(detections)} "
                                                 "frames; expected one (is marker_dictionary right?)")
        return chosen
    if settings.marker_id not in seen:
        raise InputFileError(settings.video, f"marker_id {settings.marker_id} is in none of its {len(detections)} "
                                             f"frames; {dictionary} markers found: {seen or 'none'}")
    return settings.marker_id


def _selector_opinion(cfg, track, fps: float, video: str) -> tuple[str, float]:
    """The SPEC 4 selector's model and decision frame from the marker's centre alone."""
    settings = selection_from_config(cfg, dt=1.0 / fps)
    points = PointTrack(path=video, points_world=track.t, times_s=track.frames / fps,
                        lines=track.frames + 1, metadata={})
    try:
        row, _, _ = classify_track(points, settings, fps)
    except (StslamError, ValueError, ArithmeticError, np.linalg.LinAlgError):
        return "failed", np.nan
    step = row["selection_step"]
    return row["model"], float(track.frames[int(step)]) if np.isfinite(step) else np.nan


def _axis_pixels(model, fit, T_camera_frame, K, D):
    """The fitted axis (hinge line, or the slide's line through the track) as a pixel polyline, or None."""
    if model == "static":
        return None
    if model == "revolute":
        s = np.linspace(-0.6, 0.6, AXIS_SAMPLES)  # the hinge's height above and below the marker (m)
    else:
        s = np.linspace(fit.q.min() - 0.1, fit.q.max() + 0.1, AXIS_SAMPLES)
    points = fit.point + np.outer(s, fit.axis)
    cam = points @ T_camera_frame[:3, :3].T + T_camera_frame[:3, 3]
    cam = cam[cam[:, 2] > 0.05]
    return project_points(cam, K, D) if cam.shape[0] >= 2 else None


def _scene(settings, jpegs, track, kept, fit, model, marker_id, K, D, size, fps) -> bytes:
    by_frame = {int(f): i for i, f in enumerate(track.frames)}
    corners = marker_object_points(settings.marker_length_m)
    frames = []
    T_last = np.eye(4)
    for k, jpeg in enumerate(jpegs):
        i = by_frame.get(k)
        outline = axis = centre = None
        label = f"{model}: marker {marker_id} not posed"
        if i is not None:
            T_last = track.T_camera_frame[i]
            pose_cam = T_last[:3, :3] @ track.R[i], T_last[:3, :3] @ track.t[i] + T_last[:3, 3]
            outline = project_points(corners @ pose_cam[0].T + pose_cam[1], K, D)
            centre = track.t[i]
            if kept[i] and fit.axis is not None:
                q = fit.q[int(np.count_nonzero(kept[:i]))] - fit.q[0]  # from the first pose the fit used
                label = f"{model}: {np.degrees(q):.1f}°" if model == "revolute" else f"{model}: {100 * q:.1f} cm"
            else:
                label = model if kept[i] else f"{model}: pose left out"
        if fit.axis is not None and (i is not None or settings.reference_id is None):
            axis = _axis_pixels(model, fit, T_last, K, D)
        frames.append(MarkerSceneFrame(jpeg=jpeg, outline_px=outline, axis_px=axis, label=label, centre=centre))
    joint = None if fit.axis is None else MarkerJoint(marker_id, model, fit.point, fit.axis)
    frame_id = mt.CAMERA_FRAME if settings.reference_id is None else f"marker_{settings.reference_id}"
    return marker_scene_bytes(frames, fps, K, D, size, model, joint, frame_id)


def _track_text(settings, track, kept, marker_id, fps, frame_name) -> str:
    quat = Rotation.from_matrix(track.R[kept]).as_quat()  # x, y, z, w
    metadata = {"source": f"marker {marker_id} in {settings.video}", "columns": "x,y,z,qx,qy,qz,qw",
                "frame": frame_name, "rate_hz": f"{fps:g}"}
    return format_track(track.t[kept], metadata=metadata, orientations_xyzw=quat, separator=",",
                        row_comments=[f"frame {f}" for f in track.frames[kept]])


def run(cfg: dict) -> ExperimentOutput:
    """The joint of the marker video ``video`` (module docstring)."""
    settings = marker_video_from_config(cfg)
    seed = get_int(cfg, "seed", low=0)
    selection_from_config(cfg)  # a bad selection block fails before the video is read
    calibration = read_camera_calibration(settings.calib)
    detections, jpegs, calibration, size, fps = _read_frames(settings, calibration,
                                                             bool(lookup(cfg, "progress", False)))
    K, D = calibration.K, calibration.D
    marker_id = _marker_id(settings, detections)
    track = pose_track(detections, marker_id, K, D, settings.marker_length_m, settings.reference_id,
                       sigma_px=settings.flip_sigma_px, sigma_turn_deg=settings.flip_sigma_turn_deg)
    if track.frames.size < MIN_POSES:
        with_ref = "" if settings.reference_id is None else f" together with reference marker {settings.reference_id}"
        raise InputFileError(settings.video, f"marker {marker_id} was posed{with_ref} in {track.frames.size} of "
                                             f"{len(jpegs)} frames; at least {MIN_POSES} are needed")
    d = settings.decision
    noise = estimate_pose_noise(track.t, track.R, track.frames, d.choice.min_noise_m, d.choice.min_noise_deg)
    decision = decide_model(track.t, track.R, noise, d)
    model = decision.model
    fit, kept, _ = final_fit(model, track.t, track.R, noise, d)
    check = joint_consistency(fit, d, origin_is_camera=settings.reference_id is None, noise=noise)
    if check.problems and settings.not_a_joint == "refuse":
        hint = ("; without reference_id the camera must stay still (or give reference_id=<a marker on the fixed "
                "part>)" if settings.reference_id is None else "")
        raise InputFileError(settings.video, f"the track of marker {marker_id} is not a joint: "
                                             f"{'; '.join(check.problems)}{hint}")
    decided_at = decision_frame(track.t, track.R, track.frames, noise, model, d)
    selector_model, selector_frame = _selector_opinion(cfg, track, fps, settings.video)
    frame_name = "camera" if settings.reference_id is None else f"marker_{settings.reference_id}"
    posed, left_out = int(track.frames.size), int(np.count_nonzero(~kept))
    result = {"model": model, "frames": len(jpegs), "posed": posed,
              "axis": None if fit.axis is None else fit.axis.tolist(),
              "point": fit.point.tolist() if model == "revolute" else None}
    if model == "revolute":
        result["angle_range_deg"] = float(np.degrees(motion_range(fit.q)))
    elif model == "prismatic":
        result["travel_m"] = motion_range(fit.q)
    result |= {"residual_rms_m": check.residual_rms_m, "residual_rms_deg": check.residual_rms_deg,
               "decided_at_frame": decided_at, "frame": frame_name, "marker_id": marker_id,
               "reference_id": settings.reference_id, "dictionary": settings.detection.dictionary,
               "marker_length_m": settings.marker_length_m, "flips": track.flips, "left_out": left_out, "fps": fps,
               "bic": decision.bic, "consistent": not check.problems, "warnings": list(check.problems),
               "selector": {"model": selector_model,
                            "decided_at_frame": None if np.isnan(selector_frame) else int(selector_frame)}}
    metrics = pd.DataFrame([{
        "seed": seed, "method": "marker_video", "model": model, "frames": len(jpegs), "posed": posed,
        "posed_fraction": posed / len(jpegs), "left_out": left_out, "flips": track.flips,
        "decided_at_frame": decided_at,
        "angle_range_deg": result.get("angle_range_deg", np.nan), "travel_m": result.get("travel_m", np.nan),
        "residual_rms_m": check.residual_rms_m, "residual_rms_deg": check.residual_rms_deg,
        **{f"axis_{a}": v for a, v in zip("xyz", np.full(3, np.nan) if fit.axis is None else fit.axis)},
        **{f"point_{a}": v for a, v in zip("xyz", fit.point if model == "revolute" else np.full(3, np.nan))},
        "selector_model": selector_model, "selector_frame": selector_frame}])
    scene = _scene(settings, jpegs, track, kept, fit, model, marker_id, K, D, size, fps)
    amount = (f", opening {result['angle_range_deg']:.1f}°" if model == "revolute" else
              f", travel {100 * result['travel_m']:.1f} cm" if model == "prismatic" else "")
    lines = [f"warning: the track of marker {marker_id} is not a joint: {p}" for p in check.problems]
    lines.append(f"marker {marker_id}: {model}{amount}; posed in {posed} of {len(jpegs)} frames "
                 f"({track.flips} flips avoided, {left_out} poses left out of the fit), decided at frame {decided_at}, "
                 f"residual {100 * check.residual_rms_m:.1f} cm / {check.residual_rms_deg:.1f}° RMS; "
                 f"the centre's selector says {selector_model}")
    return ExperimentOutput(metrics=metrics, files={"articulation.json": json.dumps(result, indent=2) + "\n",
                                                    "track.csv": _track_text(settings, track, kept, marker_id, fps,
                                                                             frame_name)},
                            binaries={"scene.mcap": scene}, lines=lines)
