"""Calibration files (SPEC 17): OpenCV FileStorage YAML and XML, ROS camera_info YAML, and bad ones."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stslam.errors import InputFileError
from stslam.io.camera_file import read_camera_calibration, scaled_to
from stslam.io.video import VideoFrames, write_video

K = np.array([[512.0, 0.0, 319.5], [0.0, 510.0, 241.0], [0.0, 0.0, 1.0]])
D = np.array([-0.21, 0.05, 0.001, -0.002, 0.01])


def _is_the_camera(calibration, size) -> bool:
    return np.array_equal(calibration.K, K) and np.array_equal(calibration.D, D) and calibration.size == size


@pytest.mark.parametrize("suffix", [".yaml", ".xml"])
def test_opencv_filestorage_files_are_read(tmp_path, suffix):
    path = tmp_path / f"camera{suffix}"
    storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_WRITE)
    storage.write("image_width", 640)
    storage.write("image_height", 480)
    storage.write("camera_matrix", K)
    storage.write("distortion_coefficients", D.reshape(1, 5))
    storage.release()
    assert _is_the_camera(read_camera_calibration(path), (640, 480))


def test_an_old_opencv_yaml_header_is_read(tmp_path):
    path = tmp_path / "old.yml"
    path.write_text("%YAML:1.0\n---\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
                    f"   data: {K.reshape(-1).tolist()}\ndistCoeffs: !!opencv-matrix\n   rows: 1\n   cols: 4\n"
                    "   dt: d\n   data: [ -0.2, 0.05, 0., 0. ]\n")
    calibration = read_camera_calibration(path)
    np.testing.assert_array_equal(calibration.K, K)
    assert calibration.D.tolist() == [-0.2, 0.05, 0.0, 0.0] and calibration.size is None


def test_a_ros_camera_info_yaml_is_read(tmp_path):
    path = tmp_path / "head_camera.yaml"
    path.write_text("image_width: 640\nimage_height: 480\ncamera_name: head_camera\ncamera_matrix:\n  rows: 3\n"
                    f"  cols: 3\n  data: {K.reshape(-1).tolist()}\ndistortion_model: plumb_bob\n"
                    f"distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: {D.tolist()}\n"
                    "rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n")
    assert _is_the_camera(read_camera_calibration(path), (640, 480))


def test_a_calibration_without_a_camera_matrix_is_refused(tmp_path):
    path = tmp_path / "no_k.yaml"
    path.write_text("image_width: 640\ndistortion_coefficients:\n  data: [0, 0, 0, 0, 0]\n")
    with pytest.raises(InputFileError, match="no_k.yaml: no camera matrix"):
        read_camera_calibration(path)


@pytest.mark.parametrize("text, match", [
    ("camera_matrix: [1, 2, 3]\n", "expected 9 finite numbers"),
    ("camera_matrix: [-5, 0, 1, 0, 5, 1, 0, 0, 1]\n", "fx, fy > 0"),
    (f"camera_matrix: {K.reshape(-1).tolist()}\nD: [0.1, 0.2, 0.3]\n", "D: expected 4, 5, 8"),
    ("camera_matrix: [1, 2\n", "not a calibration YAML file"),
])
def test_bad_calibrations_name_what_is_wrong(tmp_path, text, match):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(InputFileError, match=match):
        read_camera_calibration(path)


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(InputFileError, match="nope.yaml: cannot be read"):
        read_camera_calibration(tmp_path / "nope.yaml")


def test_k_follows_frames_resized_and_refuses_another_shape(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text(f"image_width: 1280\nimage_height: 960\ncamera_matrix: {K.reshape(-1).tolist()}\n")
    calibration = read_camera_calibration(path)
    half = scaled_to(calibration, 640, 480)
    # pixel centres at integers: f' = f/2, c' = (c + 1/2)/2 − 1/2
    np.testing.assert_allclose(half.K, [[256.0, 0, 159.5], [0, 255.0, 120.25], [0, 0, 1]])
    with pytest.raises(InputFileError, match="another aspect ratio"):
        scaled_to(calibration, 480, 640)


def test_video_frames_round_trip_and_bad_videos(tmp_path):
    frames = [np.full((48, 64, 3), 20 * k, np.uint8) for k in range(5)]
    path = tmp_path / "clip.avi"
    assert write_video(path, frames, 30.0) == 5
    video = VideoFrames(path)
    assert video.info.size == (64, 48) and video.info.fps == 30.0
    read = list(video)
    assert len(read) == 5 and all(abs(int(f.mean()) - 20 * k) <= 2 for k, f in enumerate(read))  # MJPG: ±2 levels
    with pytest.raises(InputFileError, match="no such video file"):
        VideoFrames(tmp_path / "missing.mp4")
    junk = tmp_path / "junk.mp4"
    junk.write_bytes(b"not a video" * 100)
    with pytest.raises(InputFileError, match="cannot be read as a video"):
        VideoFrames(junk)
