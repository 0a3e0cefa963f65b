"""The RGB-D reader's single pass (stslam.io.mcap_side): frames as a separate first pass over the small topics
would give them, whatever the small topics' log times, with or without summary statistics."""

from __future__ import annotations

import functools
import itertools

import numpy as np
import pytest
from mcap.writer import Writer as McapWriter

import stslam.io.mcap_read as mcap_read
import stslam.io.mcap_write as mcap_write
from stslam.errors import InputFileError
from stslam.io import mcap_topics as mt
from stslam.io.mcap_read import RGBDMcapReader
from stslam.io.mcap_write import (ProtobufMcapWriter, atomic_output, calibration_message, depth_image_message,
                                  rgb_image_message, stamp_ns, transform_message, write_fridge_mcap)
from stslam.geometry import pose_matrix, rotation_z
from stslam.rgbd.sequence import FridgeSequence, SequenceConfig

K = np.array([[50.0, 0.0, 39.5], [0.0, 50.0, 29.5], [0.0, 0.0, 1.0]])


def _pose(k: int) -> np.ndarray:
    return pose_matrix(rotation_z(0.05 * k), np.array([0.1 * k, 0.02 * k * k, 0.0]))


def _write(path, n_frames: int, lag_s: float, dt_s: float = 0.1) -> None:
    """Frames every ``dt_s`` with a calibration at the first; ground truth and odometry stamped at the frames' times
    and between them but logged ``lag_s`` later (a pose published late); the camera mount once."""
    with atomic_output(path, overwrite=True) as handle:
        writer = ProtobufMcapWriter(handle)
        writer.write(mt.DEFAULT_TOPICS.calibration, calibration_message(K, 80, 60, 0), 0)
        writer.write(mt.DEFAULT_TOPICS.camera_mount, transform_message(np.eye(4), "base", "camera", 0), 0)
        messages = []
        for k in range(n_frames):
            t_ns = stamp_ns(k * dt_s)
            image = np.full((60, 80, 3), 10 * k, np.uint8)
            messages.append((t_ns, mt.DEFAULT_TOPICS.rgb, rgb_image_message(image, t_ns)))
            messages.append((t_ns, mt.DEFAULT_TOPICS.depth,
                             depth_image_message(np.full((60, 80), 1.0 + k, np.float32), t_ns, "32FC1")))
            for half in (0, 1):  # poses at the frame and half-way to the next: the frames interpolate
                stamp = stamp_ns((k + 0.5 * half) * dt_s)
                pose = _pose(2 * k + half)
                messages.append((stamp + stamp_ns(lag_s), mt.DEFAULT_TOPICS.ground_truth_base,
                                 transform_message(pose, "world", "base", stamp)))
                messages.append((stamp + stamp_ns(lag_s), mt.DEFAULT_TOPICS.odometry,
                                 transform_message(pose @ pose, "odom", "base", stamp)))
        for t_ns, topic, message in sorted(messages, key=lambda m: (m[0], m[1])):
            writer.write(topic, message, t_ns)
        writer.finish()


def _same(a, b) -> bool:
    return (a.t_s == b.t_s and np.array_equal(a.rgb, b.rgb) and np.array_equal(a.depth_m, b.depth_m, equal_nan=True)
            and all(np.array_equal(getattr(a, f), getattr(b, f))
                    for f in ("K", "T_world_base", "T_world_base_odom", "T_base_camera", "T_world_camera")))


def _side_pass_first(path) -> list:
    """The frames with the small topics read in a pass of their own first (every frame waits past the limit)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(mcap_read, "MAX_WAITING", -1)
        return list(RGBDMcapReader(path))


@pytest.mark.parametrize("lag_s", [0.0, 0.35, 5.0])
def test_one_pass_gives_the_frames_of_a_side_pass_first(tmp_path, lag_s):
    path = tmp_path / "lag.mcap"
    _write(path, 12, lag_s)
    frames = list(RGBDMcapReader(path))
    reference = _side_pass_first(path)
    assert len(frames) == len(reference) == 12
    assert all(_same(a, b) for a, b in zip(frames, reference, strict=True))
    # Frame k has the pose stamped with it (to the writer's quaternion round trip, 1e-12), also when logged 5 s late
    # (the frames wait, or the side pass is read).
    assert all(np.allclose(f.T_world_base, _pose(2 * k), rtol=0, atol=1e-12) for k, f in enumerate(frames))


def test_a_recording_of_ours_is_read_in_one_pass(tmp_path, monkeypatch):
    path = tmp_path / "fridge.mcap"
    write_fridge_mcap(path, FridgeSequence(SequenceConfig(n_frames=10, width=80, height=60), 2))
    reference = _side_pass_first(path)

    def refuse(self):
        raise AssertionError("the small topics were read in a pass of their own")

    monkeypatch.setattr(RGBDMcapReader, "_full_side_pass", refuse)
    reader = RGBDMcapReader(path)
    frames = list(reader)
    assert all(_same(a, b) and a.door.angle_rad == b.door.angle_rad for a, b in zip(frames, reference, strict=True))
    assert [f.t_s for f in reader] == [f.t_s for f in frames]  # a second iteration reuses the small topics
    partial = RGBDMcapReader(path)
    assert [f.t_s for f in itertools.islice(partial, 3)] == [f.t_s for f in frames[:3]]
    # after an iteration broken off, the next one starts the small topics afresh (no stamp seen twice)
    assert all(_same(a, b) for a, b in zip(partial, reference, strict=True))


def test_without_summary_statistics_the_frames_are_the_same(tmp_path, monkeypatch):
    with_stats, without = tmp_path / "stats.mcap", tmp_path / "nostats.mcap"
    _write(with_stats, 6, 0.2)
    monkeypatch.setattr(mcap_write, "McapWriter", functools.partial(McapWriter, use_statistics=False))
    _write(without, 6, 0.2)
    assert RGBDMcapReader(without).n_rgb_messages == 0  # (no statistics: the count is unknown)
    frames = list(RGBDMcapReader(without))
    assert all(_same(a, b) for a, b in zip(frames, list(RGBDMcapReader(with_stats)), strict=True))


def test_a_third_child_frame_is_named_when_it_appears(tmp_path):
    path = tmp_path / "children.mcap"
    with atomic_output(path, overwrite=True) as handle:
        writer = ProtobufMcapWriter(handle)
        writer.write(mt.DEFAULT_TOPICS.calibration, calibration_message(K, 80, 60, 0), 0)
        for k, child in enumerate(("base", "base_link")):
            t_ns = stamp_ns(0.1 * k)
            writer.write(mt.DEFAULT_TOPICS.ground_truth_base, transform_message(np.eye(4), "world", child, t_ns), t_ns)
            writer.write(mt.DEFAULT_TOPICS.rgb, rgb_image_message(np.zeros((60, 80, 3), np.uint8), t_ns), t_ns)
            writer.write(mt.DEFAULT_TOPICS.depth, depth_image_message(np.ones((60, 80), np.float32), t_ns, "32FC1"),
                         t_ns)
        writer.finish()
    with pytest.raises(InputFileError, match=r"children\.mcap: topic /ground_truth/base: expected 1 child "
                                             r"frame\(s\), got base, base_link"):
        list(RGBDMcapReader(path))
