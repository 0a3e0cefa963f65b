"""+exp=marker_video (SPEC 17) on videos rendered with known truth, and bad inputs from the command line.

Videos: 320 × 240, 90 frames (3 s at 30 Hz), a 15 cm marker ~1.6 m away (about 30 px across) through a
barrel-distorting lens, motion blur over half a frame, Gaussian blur and pixel noise, MJPG-compressed.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import cv2
import numpy as np
import pandas as pd
import pytest
from mcap.reader import make_reader

from stslam.errors import InputFileError
from stslam.experiments import marker_video
from stslam.experiments.runner import execute
from stslam.geometry import axis_angle_deg, axis_line_distance
from stslam.io.results import complete_runs
from stslam.io.video import write_video
from stslam.sim.marker_video import MarkerVideoRenderer, MarkerVideoScene

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "experiments"))
from make_marker_video import DRAWER_DEFAULTS, write_calibration  # noqa: E402

VIDEOS = {
    "door": {"kind": "door", "seed": 1},
    "drawer": {"kind": "drawer", "seed": 2, **DRAWER_DEFAULTS},
    "door_moving_camera": {"kind": "door", "seed": 3, "reference_id": 3, "camera_shake_m": 0.15},
}


@pytest.fixture(scope="module")
def videos(tmp_path_factory):
    """name → (video path, calibration path, truth) of each rendered video."""
    folder = tmp_path_factory.mktemp("marker_videos")
    out = {}
    for name, options in VIDEOS.items():
        renderer = MarkerVideoRenderer(MarkerVideoScene(**options))
        path = folder / f"{name}.avi"
        write_video(path, renderer.frames(), renderer.scene.fps)
        write_calibration(folder / f"{name}.yaml", renderer.K, renderer.D, (320, 240))
        out[name] = (path, folder / f"{name}.yaml", renderer.truth())
    return out


def _overrides(video, calib, *extra):
    return (f"video={video}", f"calib={calib}", "marker_length=0.15", "marker_dictionary=DICT_6X6_250", *extra)


def _articulation(folder) -> dict:
    return json.loads((folder / "articulation.json").read_text())


def _hinge_errors(result, truth) -> tuple[float, float, float]:
    axis, point = np.array(result["axis"]), np.array(result["point"])
    return (axis_angle_deg(axis, truth["axis"]), axis_line_distance(point, axis, truth["point"], truth["axis"]),
            abs(result["angle_range_deg"] - truth["angle_range_deg"]))


def test_a_door_video_gives_its_hinge_and_opening(videos, compose_exp, capsys):
    video, calib, truth = videos["door"]
    folder = execute(compose_exp("marker_video", *_overrides(video, calib)))
    result = _articulation(folder)
    assert result["model"] == "revolute" and result["frame"] == "camera" and result["consistent"]
    angle, distance, opening = _hinge_errors(result, truth)
    # issue 41's bar: hinge ≤ 2° and 2 cm, opening within 3° (measured 0.7-1.0°, 0.4-0.6 cm, 0.7-0.9° on seeds 1-3)
    assert angle <= 2.0 and distance <= 0.02 and opening <= 3.0
    assert result["frames"] == 90 and result["posed"] >= 0.9 * 90
    assert 13 <= result["decided_at_frame"] <= 60  # the door starts to move at frame 13 (15% of 90)
    assert "revolute, opening" in capsys.readouterr().out
    # track.csv: SPEC 10's 7 columns, one row per pose the fit used, readable by classify_tracks
    rows = [line.split("#")[0].strip() for line in (folder / "track.csv").read_text().splitlines()
            if line.strip() and not line.startswith("#")]
    assert len(rows) == result["posed"] - result["left_out"] and all(len(r.split(",")) == 7 for r in rows)
    classified = execute(compose_exp("classify_tracks", f"tracks.glob={folder / 'track.csv'}", "max_figures=0"))
    assert len(pd.read_csv(classified / "metrics.csv")) == 1
    # scene.mcap: every frame with its annotations, the 3D scene, the calibration with the distortion
    with open(folder / "scene.mcap", "rb") as handle:
        summary = make_reader(handle).get_summary()
    counts = {c.topic: summary.statistics.channel_message_counts[i] for i, c in summary.channels.items()}
    assert counts == {"/camera/calibration": 1, "/camera/image": 90, "/camera/annotations": 90, "/marker": 90}
    schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
    assert schemas["/camera/image"] == "foxglove.CompressedImage" and schemas["/marker"] == "foxglove.SceneUpdate"
    # the same input gives the same numbers (SPEC 11)
    again = execute(compose_exp("marker_video", *_overrides(video, calib)))
    assert (again / "articulation.json").read_bytes() == (folder / "articulation.json").read_bytes()
    assert (again / "scene.mcap").read_bytes() == (folder / "scene.mcap").read_bytes()


def test_a_drawer_video_is_prismatic_along_its_slide(videos, compose_exp):
    video, calib, truth = videos["drawer"]
    result = _articulation(execute(compose_exp("marker_video", *_overrides(video, calib))))
    assert result["model"] == "prismatic" and result["point"] is None
    assert axis_angle_deg(np.array(result["axis"]), truth["axis"]) <= 2.0  # measured 0.3° on seeds 1-4
    assert abs(result["travel_m"] - truth["travel_m"]) <= 0.02  # measured ≤ 3 mm of 35 cm on seeds 1-4


def test_a_reference_marker_lets_the_camera_move(videos, compose_exp):
    video, calib, truth = videos["door_moving_camera"]
    result = _articulation(execute(compose_exp("marker_video", *_overrides(video, calib, "reference_id=3"))))
    assert result["model"] == "revolute" and result["frame"] == "marker_3" and truth["frame"] == "marker_3"
    angle, distance, opening = _hinge_errors(result, truth)
    # the same bar, in the reference marker's frame (measured 0.8-1.5°, 0.5-1.0 cm, 0.3-1.5° on seeds 1-4)
    assert angle <= 2.0 and distance <= 0.02 and opening <= 3.0


def test_a_moving_camera_without_a_reference_is_refused_or_flagged(videos, compose_exp, capsys):
    video, calib, _ = videos["door_moving_camera"]
    config = compose_exp("marker_video", *_overrides(video, calib, "marker_id=7"))
    with pytest.raises(InputFileError, match="is not a joint: .*reference_id"):
        execute(config)
    assert not complete_runs(config["out_dir"], "marker_video")
    warned = execute(compose_exp("marker_video", *_overrides(video, calib, "marker_id=7", "not_a_joint=warn")))
    result = _articulation(warned)
    assert not result["consistent"] and result["warnings"]
    assert "warning: the track of marker 7 is not a joint" in capsys.readouterr().out


def test_the_marker_seen_most_is_taken_and_a_missing_one_is_named(videos, compose_exp):
    video, calib, _ = videos["door_moving_camera"]  # markers 7 (door, every frame) and 3 (wall, most frames)
    with pytest.raises(InputFileError, match=r"marker_id 5 is in none of its 90 frames; DICT_6X6_250 markers "
                                             r"found: \[3, 7\]"):
        marker_video.run(compose_exp("marker_video", *_overrides(video, calib, "marker_id=5")))
    with pytest.raises(InputFileError, match=r"reference_id 4 is in none of its 90 frames"):
        marker_video.run(compose_exp("marker_video", *_overrides(video, calib, "reference_id=4")))


# ------------------------------------------------------------------------------------------ bad input
CASES = {
    "unreadable video": (["video={tmp}/junk.mp4"], r"error: .*junk\.mp4: cannot be read as a video .*"),
    "empty video": (["video={tmp}/empty.avi"], r"error: .*empty\.avi: (the video has no frames that can be decoded|"
                                               r"cannot be read as a video .*)"),
    "no marker": (["video={tmp}/blank.avi"], r"error: .*blank\.avi: no DICT_6X6_250 marker found in any of its 12 "
                                             r"frames; expected one \(is marker_dictionary right\?\)"),
    "no camera matrix": (["calib={tmp}/no_k.yaml"], r"error: .*no_k\.yaml: no camera matrix; expected .*"),
    "zero marker length": (["marker_length=0"], r"error: marker_length: expected the side of the marker's black "
                                                r"square in metres, > 0 \(e\.g\. marker_length=0\.1\), got 0"),
    "negative marker length": (["marker_length=-0.1"], r"error: marker_length: expected .*got -0\.1"),
    "unknown dictionary": (["marker_dictionary=DICT_9X9_7"], r"error: marker_dictionary: expected an OpenCV "
                                                             r"dictionary name such as .*; got 'DICT_9X9_7'"),
    "bad decision threshold": (["decision.consistency.max_residual_m=0"],
                               r"error: decision\.consistency\.max_residual_m: expected a finite number > 0\.0, "
                               r"got 0\.0"),
    "decision key outside its step": (["+decision.max_residual_m=0.05"],
                                      r"error: decision\.max_residual_m: no such setting; expected one of motion, "
                                      r"choice, consistency, checkpoints"),
}


@pytest.fixture(scope="module")
def bad_inputs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bad_marker_inputs")
    (folder / "junk.mp4").write_bytes(b"not a video" * 200)
    write_video(folder / "blank.avi", [np.full((120, 160, 3), 128, np.uint8)] * 12, 30.0)
    writer = cv2.VideoWriter(str(folder / "empty.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (160, 120))
    writer.release()
    write_calibration(folder / "good.yaml", np.array([[150.0, 0, 79.5], [0, 150.0, 59.5], [0, 0, 1]]), np.zeros(5),
                      (160, 120))
    (folder / "no_k.yaml").write_text("image_width: 160\nimage_height: 120\ndistortion_coefficients: [0, 0, 0, 0]\n")
    return folder


def _run(args, out_dir, inputs):
    base = {"video": f"video={inputs}/blank.avi", "calib": f"calib={inputs}/good.yaml",
            "marker_length": "marker_length=0.1", "marker_dictionary": "marker_dictionary=DICT_6X6_250"}
    for arg in args:
        base[arg.split("=")[0]] = arg.replace("{tmp}", str(inputs))
    return subprocess.run([sys.executable, str(REPO / "experiments" / "run.py"), "+exp=marker_video",
                           f"out_dir={out_dir}", "progress=false", *base.values()], cwd=REPO,
                          env=dict(os.environ, MPLBACKEND="Agg"), capture_output=True, text=True, timeout=300)


@pytest.fixture(scope="module")
def outcomes(bad_inputs, tmp_path_factory):
    def one(item):
        case_id, (args, _) = item
        out_dir = tmp_path_factory.mktemp("out")
        return case_id, (_run(args, out_dir, bad_inputs), out_dir)

    with ThreadPoolExecutor(max_workers=2) as pool:
        return dict(pool.map(one, CASES.items()))


@pytest.mark.parametrize("case_id", list(CASES))
def test_bad_input_ends_in_one_line_and_writes_nothing(outcomes, case_id):
    done, out_dir = outcomes[case_id]
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and re.fullmatch(CASES[case_id][1], lines[0]), done.stderr
    assert not list(Path(out_dir).rglob("articulation.json")) and not complete_runs(out_dir, "marker_video")
