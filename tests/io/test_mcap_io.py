"""MCAP writer and reader of RGB-D sequences (SPEC 9): round trip, determinism, bad files."""

from __future__ import annotations

import hashlib
import os
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hydra import compose, initialize_config_dir
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory
from omegaconf import OmegaConf
from scipy.spatial.transform import Rotation

from stslam.config.rgbd import data_request_from_config
from stslam.io import mcap_topics as mt
from stslam.experiments.datasets import generate
from stslam.errors import ConfigError, InputFileError, StslamError
from stslam.rgbd.sequence import FridgeSequence, SequenceConfig
from stslam.io.mcap_read import RGBDMcapReader, read_rgbd_frames
from stslam.io.mcap_write import (ProtobufMcapWriter, atomic_output, calibration_message, depth_image_message,
                               door_messages, rgb_image_message, stamp_ns, transform_message, write_fridge_mcap)
from stslam.geometry import planar_pose_from_matrix, rotation_about_axis, transform_points
from stslam.robot.pinhole import back_project_pixels
from stslam.robot.motion import control_between
from stslam.rgbd.scene import LABEL_DOOR_FRONT

REPO = Path(__file__).resolve().parents[2]
TINY = SequenceConfig(n_frames=8, width=80, height=60)
SEED = 4


def _sha256(path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """An 8-frame 80 × 60 sequence and its MCAP file."""
    sequence = FridgeSequence(TINY, SEED)
    path = tmp_path_factory.mktemp("mcap") / "tiny.mcap"
    write_fridge_mcap(path, sequence, metadata={"seed": SEED})
    return sequence, path


def test_round_trip_is_exact(tiny):
    sequence, path = tiny
    reader = RGBDMcapReader(path)
    frames = list(reader)
    assert len(frames) == reader.n_rgb_messages == len(sequence) and reader.skipped == 0
    assert reader.metadata[mt.METADATA_NAME] == {"seed": str(SEED)}
    for k, frame in enumerate(frames):
        truth = sequence.frame(k)
        assert frame.t_s == pytest.approx(k / TINY.rate_hz, abs=1e-9)  # stamps are rounded to 1 ns
        np.testing.assert_array_equal(frame.rgb, truth.rgb)
        np.testing.assert_array_equal(frame.depth_m, truth.depth_m)  # NaN holes compare equal here
        assert np.isnan(frame.depth_m).any()  # the tiny views include out-of-range wall
        np.testing.assert_array_equal(frame.K, sequence.K)
        # Poses pass through quaternions: exact to a few float64 ulps.
        np.testing.assert_allclose(frame.T_world_base, truth.T_world_base, atol=1e-12)
        np.testing.assert_allclose(frame.T_world_base_odom, truth.T_world_base_odom, atol=1e-12)
        np.testing.assert_allclose(frame.T_base_camera, sequence.T_base_camera, atol=1e-12)
        np.testing.assert_allclose(frame.T_world_camera, sequence.T_world_camera(k), atol=1e-12)
        np.testing.assert_allclose(frame.door.hinge_point_world, sequence.hinge_point_world, atol=1e-12)
        np.testing.assert_allclose(frame.door.hinge_axis_world, sequence.hinge_axis_world, atol=1e-12)
        assert frame.door.angle_rad == pytest.approx(truth.door_angle_rad, abs=1e-12)
        np.testing.assert_allclose(frame.door.closed_direction_world, sequence.room.door_closed_direction_world,
                                   atol=1e-12)


def test_back_projection_with_the_recorded_calibration_and_pose_lands_on_the_recorded_door(tmp_path):
    """K, T_world_camera and the door encoding as read back: door pixels back-project onto the door panel."""
    sequence = FridgeSequence(replace(TINY, n_frames=30, width=160, height=120, depth_noise_coefficient=0.0), 1)
    path = tmp_path / "exact.mcap"
    write_fridge_mcap(path, sequence)
    checked = 0
    for k, frame in enumerate(read_rgbd_frames(path)):
        if k % 6:
            continue
        v, u = np.nonzero((sequence.render(k).label == LABEL_DOOR_FRONT) & np.isfinite(frame.depth_m))
        points = transform_points(frame.T_world_camera,
                                  back_project_pixels(frame.K, np.column_stack([u, v]), frame.depth_m[v, u]))
        door = frame.door
        # The front face contains the hinge axis and the closed-panel direction turned by φ about it.
        along = rotation_about_axis(door.hinge_axis_world, door.angle_rad) @ door.closed_direction_world
        normal = np.cross(door.hinge_axis_world, along)
        # float32 depth (≤ 3 m: 0.2 µm) and pixel-centre geometry are exact; allow 10 µm.
        np.testing.assert_allclose((points - door.hinge_point_world) @ normal, 0.0, atol=1e-5)
        width = (points - door.hinge_point_world) @ along
        assert width.min() > -0.01 and width.max() < 0.81  # the 0.8 m panel, from its hinge
        checked += 1
    assert checked == 5


def test_odometry_controls_are_recovered_from_the_recorded_poses(tiny):
    sequence, path = tiny
    poses = [planar_pose_from_matrix(frame.T_world_base_odom) for frame in read_rgbd_frames(path)]
    dt = 1.0 / TINY.rate_hz
    recovered = [control_between(poses[k], poses[k + 1], dt) for k in range(len(poses) - 1)]
    # Inverting the arc model (SPEC 5.1) on poses exact to 1e-12 m gives v, ω to ~1e-9.
    np.testing.assert_allclose(recovered, sequence.controls_odom_vw, atol=1e-8)


def test_documented_topics_and_schemas_with_the_plain_mcap_reader(tiny):
    _, path = tiny
    with open(path, "rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        assert reader.get_header().library == "stslam-rgbd-mcap/1"
        seen = {}
        for schema, channel, _, decoded in reader.iter_decoded_messages():
            seen.setdefault(channel.topic, (schema.name, channel.message_encoding, set()))[2].add(
                getattr(decoded, "encoding", None) or getattr(decoded, "child_frame_id", None)
                or decoded.frame_id)
    t = mt.DEFAULT_TOPICS
    assert seen == {
        t.rgb: ("foxglove.RawImage", "protobuf", {"rgb8"}),
        t.depth: ("foxglove.RawImage", "protobuf", {"32FC1"}),
        t.calibration: ("foxglove.CameraCalibration", "protobuf", {"camera_optical"}),
        t.ground_truth_base: ("foxglove.FrameTransform", "protobuf", {"base_link"}),
        t.odometry: ("foxglove.FrameTransform", "protobuf", {"base_link_odom"}),
        t.camera_mount: ("foxglove.FrameTransform", "protobuf", {"camera_optical"}),
        t.door: ("foxglove.FrameTransform", "protobuf", {"door_hinge", "door_panel"}),
    }


def test_same_seed_gives_the_same_bytes(tmp_path, tiny):
    sequence, path = tiny
    again = tmp_path / "again.mcap"
    write_fridge_mcap(again, FridgeSequence(TINY, SEED), metadata={"seed": SEED})
    assert _sha256(again) == _sha256(path)
    other = tmp_path / "other.mcap"
    write_fridge_mcap(other, FridgeSequence(TINY, SEED + 1), metadata={"seed": SEED + 1})
    assert _sha256(other) != _sha256(path)


def test_depth_in_millimetres_round_trips_to_the_nearest_millimetre(tmp_path, tiny):
    sequence, _ = tiny
    path = tmp_path / "mm.mcap"
    write_fridge_mcap(path, sequence, depth_encoding="16UC1")
    for k, frame in enumerate(read_rgbd_frames(path)):
        truth = sequence.frame(k).depth_m
        np.testing.assert_array_equal(np.isnan(frame.depth_m), np.isnan(truth))
        valid = np.isfinite(truth)
        assert np.abs(frame.depth_m[valid] - truth[valid]).max() <= 0.5e-3 + 1e-6  # rounding to 1 mm


def test_existing_file_is_not_replaced_without_overwrite(tmp_path):
    path = tmp_path / "x.mcap"
    path.write_bytes(b"keep me")
    with pytest.raises(StslamError, match="already exists; pass overwrite=true"):
        with atomic_output(path) as handle:
            handle.write(b"new")
    assert path.read_bytes() == b"keep me"
    with atomic_output(path, overwrite=True) as handle:
        handle.write(b"new")
    assert path.read_bytes() == b"new"
    with pytest.raises(RuntimeError, match="boom"):  # a failed write leaves neither file nor temporary
        with atomic_output(tmp_path / "y.mcap") as handle:
            handle.write(b"half")
            raise RuntimeError("boom")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["x.mcap"]


# --- bad files -------------------------------------------------------------------------------------------

def _write_custom(path, frames, topics=mt.DEFAULT_TOPICS, with_calibration=True, extra=()):
    """An MCAP with per-frame (t_s, rgb RawImage, depth RawImage), a calibration for 80 × 60
    and ``extra`` (topic, message, t_ns) messages first."""
    K = np.array([[50.0, 0.0, 39.5], [0.0, 50.0, 29.5], [0.0, 0.0, 1.0]])
    with atomic_output(path, overwrite=True) as handle:
        writer = ProtobufMcapWriter(handle)
        for topic, message, t_ns in extra:
            writer.write(topic, message, t_ns)
        for t_s, rgb, depth in frames:
            t_ns = stamp_ns(t_s)
            if with_calibration:
                writer.write(topics.calibration, calibration_message(K, 80, 60, t_ns), t_ns)
            if rgb is not None:
                writer.write(topics.rgb, rgb, t_ns)
            if depth is not None:
                writer.write(topics.depth, depth, t_ns)
        writer.finish()
    return path


def _rgb(t_s, w=80, h=60):
    return rgb_image_message(np.full((h, w, 3), 100, np.uint8), stamp_ns(t_s))


def _depth(t_s, w=80, h=60, encoding="32FC1"):
    return depth_image_message(np.full((h, w), 2.0, np.float32), stamp_ns(t_s), encoding)


def test_truncated_file_is_rejected(tmp_path, tiny):
    _, path = tiny
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    with pytest.raises(InputFileError, match=r"cut\.mcap: not a complete, readable MCAP file"):
        list(read_rgbd_frames(cut))


def test_not_an_mcap_and_missing_file_are_rejected(tmp_path):
    text = tmp_path / "notes.mcap"
    text.write_text("hello, this is not an MCAP file at all\n" * 3)
    with pytest.raises(InputFileError, match=r"notes\.mcap: not a complete, readable MCAP file"):
        RGBDMcapReader(text)
    with pytest.raises(InputFileError, match=r"absent\.mcap: no such file"):
        RGBDMcapReader(tmp_path / "absent.mcap")


def test_file_without_topics_is_rejected(tmp_path):
    path = _write_custom(tmp_path / "empty.mcap", [], with_calibration=False)
    with pytest.raises(InputFileError,
                       match=r"empty\.mcap: topic /camera/rgb/image: missing \(topics present: none\)"):
        RGBDMcapReader(path)


def test_missing_depth_topic_is_named(tmp_path):
    path = _write_custom(tmp_path / "nodepth.mcap", [(0.0, _rgb(0.0), None)])
    with pytest.raises(InputFileError, match=r"topic /camera/depth/image: missing"):
        RGBDMcapReader(path)


def test_unknown_encodings_are_rejected(tmp_path):
    rgb = _rgb(0.0)
    rgb.encoding = "rgb16"
    path = _write_custom(tmp_path / "rgb16.mcap", [(0.0, rgb, _depth(0.0))])
    with pytest.raises(InputFileError,
                       match=r"rgb16\.mcap: topic /camera/rgb/image: unsupported colour encoding 'rgb16'"):
        list(read_rgbd_frames(path))
    depth = _depth(0.0)
    depth.encoding = "32FC3"
    path = _write_custom(tmp_path / "fc3.mcap", [(0.0, _rgb(0.0), depth)])
    with pytest.raises(InputFileError, match=r"topic /camera/depth/image: unsupported depth encoding '32FC3'"):
        list(read_rgbd_frames(path))


def test_mismatched_sizes_are_rejected(tmp_path):
    path = _write_custom(tmp_path / "sizes.mcap", [(0.0, _rgb(0.0), _depth(0.0, w=40, h=30))])
    with pytest.raises(InputFileError, match=r"depth image is 40 × 30 but /camera/rgb/image is 80 × 60"):
        list(read_rgbd_frames(path))
    path = _write_custom(tmp_path / "calib.mcap", [(0.0, _rgb(0.0, w=64, h=48), _depth(0.0, w=64, h=48))])
    with pytest.raises(InputFileError, match=r"calibration is for 80 × 60 images but /camera/rgb/image is 64 × 48"):
        list(read_rgbd_frames(path))
    short = _rgb(0.0)
    short.data = short.data[:100]
    path = _write_custom(tmp_path / "short.mcap", [(0.0, short, _depth(0.0))])
    with pytest.raises(InputFileError, match=r"rgb8 image of 80 × 60 needs step ≥ 240 and 14400 bytes"):
        list(read_rgbd_frames(path))


def test_time_going_backwards_is_rejected(tmp_path):
    # Logged in order, but the third colour image carries a stamp earlier than the second's.
    frames = [(0.0, _rgb(0.0), _depth(0.0)), (0.1, _rgb(0.1), _depth(0.1)), (0.2, _rgb(0.02), _depth(0.2))]
    path = _write_custom(tmp_path / "back.mcap", frames)
    with pytest.raises(InputFileError, match=r"topic /camera/rgb/image: time stamps must increase, got 0\.02"):
        list(read_rgbd_frames(path))


def test_wrong_schema_on_a_topic_is_rejected(tmp_path):
    path = tmp_path / "schema.mcap"
    with atomic_output(path) as handle:
        writer = ProtobufMcapWriter(handle)
        writer.write(mt.DEFAULT_TOPICS.rgb, transform_message(np.eye(4), "world", "x", 0), 0)
        writer.write(mt.DEFAULT_TOPICS.depth, _depth(0.0), 0)
        writer.write(mt.DEFAULT_TOPICS.calibration, calibration_message(np.eye(3), 80, 60, 0), 0)
        writer.finish()
    with pytest.raises(InputFileError, match=r"topic /camera/rgb/image: expected protobuf foxglove.RawImage or "
                                             r"foxglove.CompressedImage, got protobuf foxglove.FrameTransform"):
        RGBDMcapReader(path)


def test_compressed_and_other_raw_images_read_as_the_raw_ones(tmp_path, tiny):
    """A recording as other tools write it: PNG colour and 16-bit PNG depth (mm) as foxglove.CompressedImage,
    or colour as bgra8 (an Azure Kinect): the same frames, to the millimetre for depth."""
    import cv2
    from foxglove_schemas_protobuf.CompressedImage_pb2 import CompressedImage
    from foxglove_schemas_protobuf.RawImage_pb2 import RawImage

    _, path = tiny
    frames = list(RGBDMcapReader(path))

    def compressed(t_s, image, fmt):
        ok, data = cv2.imencode(f".{fmt}", image)
        assert ok
        message = CompressedImage(frame_id=mt.CAMERA_FRAME, format=fmt, data=data.tobytes())
        message.timestamp.FromNanoseconds(stamp_ns(t_s))
        return message

    def bgra(t_s, rgb):
        h, w = rgb.shape[:2]
        data = np.dstack([rgb[..., ::-1], np.full((h, w), 255, np.uint8)]).tobytes()
        message = RawImage(frame_id=mt.CAMERA_FRAME, width=w, height=h, encoding="bgra8", step=4 * w, data=data)
        message.timestamp.FromNanoseconds(stamp_ns(t_s))
        return message

    mm = [np.where(np.isfinite(f.depth_m), np.rint(f.depth_m * 1000.0), 0).astype(np.uint16) for f in frames]
    written = [(f.t_s, compressed(f.t_s, f.rgb[..., ::-1], "png"), compressed(f.t_s, d, "png"))
               for f, d in zip(frames, mm, strict=True)]
    for name, content in (("compressed.mcap", written),
                          ("bgra.mcap", [(f.t_s, bgra(f.t_s, f.rgb), depth) for f, (_, _, depth) in
                                         zip(frames, written, strict=True)])):
        got = list(RGBDMcapReader(_write_custom(tmp_path / name, content)))
        assert len(got) == len(frames)
        for a, b in zip(frames, got, strict=True):
            np.testing.assert_array_equal(a.rgb, b.rgb)  # PNG and bgra8 are lossless
            np.testing.assert_array_equal(np.isnan(a.depth_m), np.isnan(b.depth_m))
            np.testing.assert_allclose(a.depth_m, b.depth_m, atol=0.5e-3 + 1e-6, equal_nan=True)  # mm rounding


def test_poses_as_frame_transforms_or_pose_in_frame_read_as_frame_transform(tmp_path, tiny):
    """Pose topics as other tools log them: the true base as foxglove.PoseInFrame, odometry and the door's two
    transforms batched in foxglove.FrameTransforms: the same poses and door as the generator's FrameTransforms."""
    from foxglove_schemas_protobuf.FrameTransforms_pb2 import FrameTransforms
    from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame

    _, path = tiny
    frames = list(RGBDMcapReader(path))
    topics = mt.DEFAULT_TOPICS
    extra = []
    for f in frames:
        t_ns = stamp_ns(f.t_s)
        truth = transform_message(f.T_world_base, mt.WORLD_FRAME, mt.BASE_FRAME, t_ns)
        pose = PoseInFrame(frame_id=mt.WORLD_FRAME)
        pose.timestamp.CopyFrom(truth.timestamp)
        pose.pose.position.CopyFrom(truth.translation)
        pose.pose.orientation.CopyFrom(truth.rotation)
        odometry = FrameTransforms(transforms=[transform_message(f.T_world_base_odom, mt.WORLD_FRAME,
                                                                 mt.ODOM_BASE_FRAME, t_ns)])
        door = FrameTransforms(transforms=list(door_messages(f.door.hinge_point_world, f.door.hinge_axis_world,
                                                             f.door.closed_direction_world, f.door.angle_rad, t_ns)))
        extra += [(topics.ground_truth_base, pose, t_ns), (topics.odometry, odometry, t_ns), (topics.door, door, t_ns)]
    t0 = stamp_ns(frames[0].t_s)
    extra.append((topics.camera_mount, transform_message(frames[0].T_base_camera, mt.BASE_FRAME, mt.CAMERA_FRAME,
                                                         t0), t0))
    content = [(f.t_s, rgb_image_message(f.rgb, stamp_ns(f.t_s)), depth_image_message(f.depth_m, stamp_ns(f.t_s)))
               for f in frames]
    got = list(RGBDMcapReader(_write_custom(tmp_path / "poses.mcap", content, extra=extra)))
    assert len(got) == len(frames)
    for a, b in zip(frames, got, strict=True):
        for field in ("T_world_base", "T_world_base_odom", "T_base_camera", "T_world_camera"):
            np.testing.assert_allclose(getattr(b, field), getattr(a, field), atol=1e-12, err_msg=field)
        assert b.door.angle_rad == pytest.approx(a.door.angle_rad, abs=1e-12)
        np.testing.assert_allclose(b.door.hinge_axis_world, a.door.hinge_axis_world, atol=1e-12)
    bad = [(topics.door, PoseInFrame(frame_id=mt.WORLD_FRAME), t0)]
    with pytest.raises(InputFileError, match=r"topic /door/ground_truth: expected protobuf foxglove.FrameTransform "
                                             r"or foxglove.FrameTransforms, got protobuf foxglove.PoseInFrame"):
        RGBDMcapReader(_write_custom(tmp_path / "door.mcap", content[:1], extra=bad))


def test_rgb_without_a_depth_image_in_time_is_skipped_and_counted(tmp_path):
    frames = [(0.0, _rgb(0.0), _depth(0.0)), (0.1, _rgb(0.1), _depth(0.15)), (0.2, _rgb(0.2), _depth(0.2))]
    reader = RGBDMcapReader(_write_custom(tmp_path / "gap.mcap", frames), max_depth_offset_s=0.02)
    assert [round(f.t_s, 3) for f in reader] == [0.0, 0.2] and reader.skipped == 1
    lone = _write_custom(tmp_path / "lone.mcap", [(0.0, _rgb(0.0), None), (0.5, None, _depth(0.5))])
    with pytest.raises(InputFileError, match=r"topic /camera/depth/image: no depth image within 0\.02 s"):
        list(read_rgbd_frames(lone))


def test_poses_are_interpolated_at_image_times_and_left_out_beyond_their_span(tmp_path):
    topic = mt.DEFAULT_TOPICS.ground_truth_base
    T0, T1 = np.eye(4), np.eye(4)
    T1[:3, :3] = Rotation.from_euler("z", 0.4).as_matrix()
    T1[:3, 3] = [1.0, -2.0, 0.0]
    extra = [(topic, transform_message(T0, "world", "base_link", 0), 0),
             (topic, transform_message(T1, "world", "base_link", stamp_ns(0.2)), stamp_ns(0.2))]
    frames = [(t, _rgb(t), _depth(t)) for t in (0.05, 0.2, 0.24, 0.3)]
    got = [f.T_world_base for f in read_rgbd_frames(_write_custom(tmp_path / "poses.mcap", frames, extra=extra),
                                                     max_pose_offset_s=0.05)]
    # At 0.05 s, a quarter of the way: translation and yaw (slerp about one axis is linear in angle).
    np.testing.assert_allclose(got[0][:3, 3], [0.25, -0.5, 0.0], atol=1e-12)
    assert np.arctan2(got[0][1, 0], got[0][0, 0]) == pytest.approx(0.1, abs=1e-12)
    np.testing.assert_allclose(got[1], T1, atol=1e-12)
    np.testing.assert_allclose(got[2], T1, atol=1e-12)  # 0.04 s past the last pose: the last pose
    assert got[3] is None  # 0.1 s past it: unknown


def test_bgr_and_mono_images_are_read_as_rgb(tmp_path):
    bgr = np.zeros((60, 80, 3), np.uint8)
    bgr[..., 0], bgr[..., 2] = 10, 200  # blue 10, red 200
    bgr_msg = rgb_image_message(bgr, 0)
    bgr_msg.encoding = "bgr8"
    mono_msg = rgb_image_message(np.zeros((60, 80, 3), np.uint8), stamp_ns(0.1))
    mono_msg.encoding, mono_msg.step, mono_msg.data = "mono8", 80, bytes(range(80)) * 60
    frames = list(read_rgbd_frames(_write_custom(tmp_path / "enc.mcap", [(0.0, bgr_msg, _depth(0.0)),
                                                                         (0.1, mono_msg, _depth(0.1))])))
    assert tuple(frames[0].rgb[0, 0]) == (200, 0, 10)
    assert tuple(frames[1].rgb[3, 7]) == (7, 7, 7)


@pytest.fixture(scope="module")
def tiny_bytes(tmp_path_factory):
    """A 3-frame 32 × 24 sequence as bytes, for mutation."""
    path = tmp_path_factory.mktemp("fuzz") / "fuzz.mcap"
    write_fridge_mcap(path, FridgeSequence(replace(TINY, n_frames=3, width=32, height=24), 0))
    return path.read_bytes()


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_damaged_files_yield_frames_or_input_file_error(tmp_path, tiny_bytes, data):
    """Random byte changes or a truncation: the reader yields frames or raises InputFileError, nothing else."""
    raw = bytearray(tiny_bytes)
    if data.draw(st.booleans(), label="truncate"):
        raw = raw[:data.draw(st.integers(0, len(raw) - 1), label="length")]
    else:
        for _ in range(data.draw(st.integers(1, 8), label="n_changes")):
            raw[data.draw(st.integers(0, len(raw) - 1))] = data.draw(st.integers(0, 255))
    path = tmp_path / "damaged.mcap"
    path.write_bytes(bytes(raw))
    try:
        for frame in read_rgbd_frames(path):
            assert frame.rgb.dtype == np.uint8 and frame.depth_m.dtype == np.float32
    except InputFileError as error:
        assert str(error).startswith(str(path))


# --- the make_data entry point -----------------------------------------------------------------------------

def _make_data_request(*overrides):
    with initialize_config_dir(config_dir=str(REPO / "conf"), version_base="1.3"):
        cfg = compose("make_data", overrides=["+data=fridge", "progress=false", *overrides])
    return data_request_from_config(OmegaConf.to_container(cfg, resolve=True, throw_on_missing=True))


def test_make_data_writes_mcap_and_preview_and_matches_the_command_line(tmp_path):
    small = ["n_frames=4", "width=48", "height=36", "seed=2"]
    out = tmp_path / "data" / "fridge.mcap"
    report = generate(_make_data_request(*small, f"out={out}"))
    assert report.path == out and report.n_frames == 4
    assert all(p.exists() and p.stat().st_size > 0 for p in report.previews)
    assert [p.name for p in report.previews] == ["fridge_preview.png", "fridge_preview.pdf"]
    with pytest.raises(ConfigError, match=r"^out: .*fridge\.mcap already exists; pass overwrite=true"):
        generate(_make_data_request(*small, f"out={out}"))
    generate(_make_data_request(*small, f"out={out}", "overwrite=true"))

    # The command line in a fresh process (another hash seed) writes the same bytes.
    cli_out = tmp_path / "cli.mcap"
    env = dict(os.environ, PYTHONHASHSEED="123")
    done = subprocess.run([sys.executable, str(REPO / "experiments" / "make_data.py"), "+data=fridge",
                           "progress=false", *small, f"out={cli_out}"], capture_output=True, text=True,
                          cwd=tmp_path, env=env, timeout=300)
    assert done.returncode == 0, done.stderr
    assert f"wrote {cli_out} (4 frames" in done.stdout
    assert _sha256(cli_out) == _sha256(out)

    bad = subprocess.run([sys.executable, str(REPO / "experiments" / "make_data.py"), "+data=fridge",
                          "width=8", f"out={tmp_path / 'bad.mcap'}"], capture_output=True, text=True,
                         cwd=tmp_path, env=env, timeout=300)
    assert bad.returncode == 2
    assert bad.stderr.strip() == "error: width: expected an integer ≥ 16 and ≤ 8192, got 8"
    assert not (tmp_path / "bad.mcap").exists()
