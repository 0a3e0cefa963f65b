"""The scene of a SLAM run (SPEC 15): A-SLAM's run watched by a recorder, encoded by :mod:`stslam.io.scene_mcap`.

Both drivers pass the A-SLAM run they score a
:class:`~stslam.slam.scene_record.SceneRecorder` as its observer (the recorder
only reads the state). Without A-SLAM among the methods the scene has the
trajectories and no landmarks.
"""

from __future__ import annotations

import numpy as np

from stslam.io.mcap_read import RGBDMcapReader
from stslam.io.scene_mcap import Scene, SceneFrame, scene_mcap_bytes
from stslam.slam.scene_record import landmark_frames

SCENE_NAME = "scene.mcap"


def scene_file(n_scenes: int, seed: int) -> str:
    """Results-folder name: ``scene.mcap`` for one scene, ``scene_seed<k>.mcap`` for several."""
    return SCENE_NAME if n_scenes == 1 else f"scene_seed{seed}.mcap"


def _frames_of(recorder, aslam_track, n_frames: int) -> list:
    if aslam_track is None or recorder is None or not recorder.records:
        return [None] * n_frames
    return landmark_frames(recorder, aslam_track.landmarks)


def _landmark_fields(frame) -> dict:
    if frame is None:
        return {"ids": np.zeros(0, int), "positions": np.zeros((0, 3)), "models": ()}
    return {"ids": frame.ids, "positions": frame.positions, "models": frame.models, "joints": frame.joints,
            "mu": frame.mu}


def dynamic_slam_scene(world, result, recorder) -> bytes:
    """Scene of one simulated seed: true and estimated paths, A-SLAM's landmarks, the true landmarks.

    ``result`` is the seed's :class:`stslam.slam.evaluation.SeedResult`; ``recorder`` watched its
    A-SLAM run (None without A-SLAM).
    """
    times = np.arange(world.n_frames) * world.dt
    frames = _frames_of(recorder, result.tracks.get("a_slam"), world.n_frames)
    paths = {"groundtruth": world.poses_xytheta, **{m: t.poses_xytheta for m, t in result.tracks.items()}}
    scene_frames = (SceneFrame(t_s=float(times[k]), true_positions=world.positions[k], **_landmark_fields(f))
                    for k, f in enumerate(frames))
    estimate = "a_slam" if "a_slam" in paths else next(iter(result.tracks))
    return scene_mcap_bytes(Scene(times_s=times, paths=paths, frames=scene_frames, estimate=estimate))


def _fridge_frames(tracks, frames):
    """Scene frames with the recording's colour images and tracked corners, streamed from its MCAP."""
    for k, (image, f) in enumerate(zip(RGBDMcapReader(tracks.path, tracks.topics), frames, strict=False)):
        models = dict(zip(f.ids.tolist(), f.models, strict=True)) if f is not None else {}
        observed = tracks.frames[k]
        corner_models = tuple(models.get(int(i), "undecided") for i in observed.track_ids)
        yield SceneFrame(t_s=float(tracks.times_s[k]), image_rgb=image.rgb, corners_uv=observed.pixels_uv,
                         corner_models=corner_models, **_landmark_fields(f))


def fridge_scene(tracks, poses: dict, recorder, aslam_track) -> bytes:
    """Scene of one recording: paths (true if recorded), A-SLAM's landmarks, images with tracked corners.

    ``recorder`` watched A-SLAM's run, whose result is ``aslam_track`` (None without A-SLAM).
    """
    frames = _frames_of(recorder, aslam_track, tracks.n_frames)
    paths = ({"groundtruth": tracks.poses_gt_xytheta} if tracks.has_ground_truth else {}) | dict(poses)
    estimate = "a_slam" if "a_slam" in paths else "odometry"
    width, height = tracks.image_size
    return scene_mcap_bytes(Scene(times_s=tracks.times_s, paths=paths, frames=_fridge_frames(tracks, frames),
                                  estimate=estimate, K=tracks.K, T_base_camera=tracks.T_base_camera,
                                  image_size=(width, height)))
