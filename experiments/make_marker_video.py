"""Render a marker video with known truth: ``python experiments/make_marker_video.py out=door.avi [kind=door] …``.

Writes the video (MJPG in AVI), ``<out>.calib.yaml`` (OpenCV FileStorage: camera_matrix,
distortion_coefficients, image size) and ``<out>.truth.json`` (the joint in the reporting
frame). Options (key=value): kind (door | drawer), seed, n_frames, width, height, focal_px,
marker_length_m, reference_id (a second marker on the wall), camera_shake_m (a hand-held camera).
Then e.g. ``python experiments/run.py +exp=marker_video video=door.avi calib=door.avi.calib.yaml
marker_length=0.15 marker_dictionary=DICT_6X6_250``.
"""

from __future__ import annotations

import json
import sys
from dataclasses import fields
from pathlib import Path

import cv2
import numpy as np

from stslam.io.video import write_video
from stslam.progress import progress
from stslam.sim.marker_video import MarkerVideoRenderer, MarkerVideoScene

DRAWER_DEFAULTS = {"start": 0.0, "end": 0.35, "camera_position_m": (0.9, -1.2, 1.5),
                   "camera_target_m": (0.3, -0.15, 1.0)}


def write_calibration(path, K, D, size) -> None:
    """The camera as ``cv2.FileStorage`` YAML (what a user's calibration looks like)."""
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("image_width", int(size[0]))
    storage.write("image_height", int(size[1]))
    storage.write("camera_matrix", np.asarray(K, dtype=float))
    storage.write("distortion_coefficients", np.asarray(D, dtype=float).reshape(1, -1))
    storage.release()


def make(out, **options) -> dict:
    """Render the scene of ``options`` (MarkerVideoScene fields) to ``out``; returns the truth."""
    types = {f.name: f.type for f in fields(MarkerVideoScene)}
    unknown = sorted(set(options) - set(types))
    if unknown:
        raise SystemExit(f"error: unknown option(s) {', '.join(unknown)}; expected some of {', '.join(types)}")
    if options.get("kind") == "drawer":
        options = DRAWER_DEFAULTS | options
    renderer = MarkerVideoRenderer(MarkerVideoScene(**options))
    s = renderer.scene
    write_video(out, progress(renderer.frames(), "rendering", total=s.n_frames), s.fps)
    write_calibration(f"{out}.calib.yaml", renderer.K, renderer.D, (s.width, s.height))
    truth = {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in renderer.truth().items()
             if k != "marker_poses"}
    Path(f"{out}.truth.json").write_text(json.dumps(truth, indent=2) + "\n")
    return truth


def _value(text: str):
    if text.startswith("(") and text.endswith(")"):  # a point, e.g. camera_position_m=(-1.3,-0.9,1.3)
        return tuple(float(v) for v in text[1:-1].split(","))
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return None if text == "null" else text


if __name__ == "__main__":
    args = dict(a.split("=", 1) for a in sys.argv[1:] if "=" in a)
    if "out" not in args:
        raise SystemExit("error: out=<file.avi> is required")
    target = args.pop("out")
    print(json.dumps(make(target, **{k: _value(v) for k, v in args.items()}), indent=2))
