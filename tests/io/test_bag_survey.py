"""survey_bag: topics of somebody else's bag found by what they carry, and the convert command it prints works."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from bag_writer import write_bag
from conftest import REPO
from mcap_rename import RENAMED, RENAMED_KEYS, renamed_copy
from test_rosbag_convert import TINY, settings

from stslam.io import rosbag_read as rb
from stslam.io.bag_convert import convert_bag
from stslam.io.bag_survey import image_kind, survey_bag
from stslam.io.mcap_survey import survey_recording
from stslam.io.mcap_read import RGBDMcapReader
from stslam.io.mcap_write import write_fridge_mcap
from stslam.rgbd.sequence import FridgeSequence

# An Azure Kinect on a robot with a Vicon: bgra8 colour, depth aligned to it, other names throughout.
KINECT = {"/camera/color/image_raw": "/rgb/image_raw", "/camera/aligned_depth_to_color/image_raw":
          "/depth_to_rgb/image_raw", "/camera/color/camera_info": "/rgb/camera_info", "/odom": "/wheel/odometry",
          "/mocap/base": "/vicon/robot"}


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    path = tmp_path_factory.mktemp("survey") / "tiny.mcap"
    write_fridge_mcap(path, FridgeSequence(TINY, 3))
    return path


def test_the_default_realsense_bag_needs_no_settings(tmp_path, tiny):
    survey = survey_bag(write_bag(tiny, tmp_path / "b", infrared=True))
    assert survey.overrides() == [] and survey.notes == []  # the infrared mono8 stream is not taken for colour,
    # nor counted as another colour camera
    rows = {t.topic: t for t in survey.topics}
    assert rows["/camera/color/image_raw"].detail == "bgr8 64×48" and rows["/camera/color/image_raw"].count == 8
    assert rows["/camera/infra1/image_rect_raw"].detail == "mono8 64×48"
    assert rows["/odom"].rate_hz == pytest.approx(TINY.rate_hz, rel=1e-6)  # 7 intervals over 7 frame periods


@pytest.mark.parametrize("ros", [1, 2])
def test_renamed_topics_are_found_and_the_command_converts(tmp_path, tiny, ros):
    bag = write_bag(tiny, tmp_path / ("k.bag" if ros == 1 else "k"), ros=ros, rename=KINECT, colour_encoding="bgra8")
    survey = survey_bag(bag)
    assert sorted(survey.overrides()) == sorted([
        "topics.rgb=/rgb/image_raw", "topics.depth=/depth_to_rgb/image_raw", "topics.camera_info=/rgb/camera_info",
        "topics.odometry=/wheel/odometry", "topics.ground_truth=/vicon/robot"])
    convert_bag(settings(bag, tmp_path / "out.mcap", *survey.overrides()))
    original = list(RGBDMcapReader(tiny))
    got = list(RGBDMcapReader(tmp_path / "out.mcap"))
    assert len(got) == len(original)
    for a, b in zip(original, got, strict=True):
        np.testing.assert_array_equal(a.rgb, b.rgb)
        np.testing.assert_allclose(a.T_world_base, b.T_world_base, atol=1e-9)


def test_depth_of_its_own_camera_gets_its_camera_info(tmp_path, tiny):
    K = np.array([[30.0, 0.0, 15.5], [0.0, 30.0, 11.5], [0.0, 0.0, 1.0]])
    survey = survey_bag(write_bag(tiny, tmp_path / "d", depth_camera=(K, (32, 24), np.eye(4)), infrared=True))
    assert sorted(survey.overrides()) == ["topics.depth=/camera/depth/image_rect_raw",
                                          "topics.depth_info=/camera/depth/camera_info"]
    assert "re-projected into the colour camera" in survey.notes[0]


def test_what_is_missing_is_said_and_the_cli_exits_1(tmp_path, tiny):
    # Odometry under a motion-capture name is taken for ground truth, so no odometry is left.
    bag = write_bag(tiny, tmp_path / "m", rename={"/odom": "/mocap/odom"}, ground_truth=False)
    survey = survey_bag(bag)
    assert survey.settings["topics.ground_truth"] == "/mocap/odom"
    assert any(n.startswith("cannot convert: no nav_msgs/Odometry") for n in survey.notes)
    run = subprocess.run([sys.executable, str(REPO / "experiments" / "survey_bag.py"), str(bag)],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 1 and "closest command (fix the notes first):" in run.stdout
    run = subprocess.run([sys.executable, str(REPO / "experiments" / "survey_bag.py"), str(tmp_path / "none")],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and run.stderr.startswith(f"error: {tmp_path / 'none'}: no such bag")


def test_image_kinds():
    assert image_kind(rb.IMAGE, "16UC1", "/x") == "depth" and image_kind(rb.IMAGE, "yuv422", "/x") == "colour"
    assert image_kind(rb.IMAGE, "rgb16", "/x") is None
    assert image_kind(rb.COMPRESSED, "16UC1; compressedDepth png", "/x") == "depth"
    assert image_kind(rb.COMPRESSED, "png", "/camera/depth/image/compressed") == "depth"
    assert image_kind(rb.COMPRESSED, "jpeg", "/camera/color/image/compressed") == "colour"


def test_an_mcap_gets_the_mcap_topics_of_its_own_names(tmp_path, tiny):
    survey = survey_recording(tiny)  # SPEC 9's own names: nothing to set
    assert survey.runner == "fridge" and survey.overrides() == [] and survey.notes == []
    door = next(t for t in survey.topics if t.topic == "/door/ground_truth")
    assert door.detail == "door_hinge → door_panel, world → door_hinge"
    renamed = survey_recording(renamed_copy(tiny, tmp_path / "renamed.mcap"))
    assert sorted(renamed.overrides()) == sorted(f"mcap_topics.{RENAMED_KEYS[old]}={new}"
                                                 for old, new in RENAMED.items())
    assert renamed.command().startswith(f"python experiments/run.py +exp=fridge mcap={tmp_path / 'renamed.mcap'}")
    # A ROS 2 bag's own MCAP (cdr messages) is surveyed as the bag it is.
    bag = write_bag(tiny, tmp_path / "ros2", storage="mcap")
    assert survey_recording(next(bag.glob("*.mcap"))).runner == "convert"


def test_a_second_colour_camera_is_named(tmp_path, tiny):
    # A grey stream named as a second colour camera: the colour one is taken and the other named.
    bag = write_bag(tiny, tmp_path / "two", rename={"/camera/infra1/image_rect_raw": "/camera2/color/image_raw"},
                    infrared=True)
    survey = survey_bag(bag)
    assert survey.settings["topics.rgb"] == "/camera/color/image_raw"
    assert ("colour taken from /camera/color/image_raw; other colour cameras: /camera2/color/image_raw"
            in survey.notes)
