"""Salvage of damaged or unfinished MCAP files: what is complete is kept exactly, nothing else, nothing overwritten."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from mcap.records import Message
from mcap.stream_reader import StreamReader

from stslam.errors import InputFileError, StslamError
from stslam.io.mcap_read import RGBDMcapReader
from stslam.io.mcap_salvage import salvage_mcap
from stslam.io.mcap_write import write_fridge_mcap
from stslam.rgbd.sequence import FridgeSequence, SequenceConfig

REPO = Path(__file__).resolve().parents[2]
# Small chunks (one frame's images are ~33 kB before compression at 80 × 60), so that a cut file
# has complete chunks before the one it ends in, as a recorder's ~1 MB chunks do on a long recording.
CHUNK = 40_000


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A 12-frame 80 × 60 recording in small chunks, its bytes and its messages in file order."""
    path = tmp_path_factory.mktemp("salvage") / "rec.mcap"
    write_fridge_mcap(path, FridgeSequence(SequenceConfig(n_frames=12, width=80, height=60), 3),
                      metadata={"seed": 3}, chunk_size=CHUNK)
    return path, path.read_bytes(), _messages(path)


def _messages(path) -> list[tuple[str, int, int, bytes]]:
    """(topic, log time, sequence, data) of every message, in file order."""
    topics, out = {}, []
    with open(path, "rb") as handle:
        for record in StreamReader(handle).records:
            if type(record).__name__ == "Channel":
                topics.setdefault(record.id, record.topic)
            elif isinstance(record, Message):
                out.append((topics[record.channel_id], record.log_time, record.sequence, bytes(record.data)))
    return out


def _frames_equal(a, b) -> bool:
    return (a.t_s == b.t_s and np.array_equal(a.rgb, b.rgb) and np.array_equal(a.depth_m, b.depth_m, equal_nan=True)
            and np.array_equal(a.T_world_base, b.T_world_base) and a.door.angle_rad == b.door.angle_rad)


def test_a_complete_file_is_copied_whole(recording, tmp_path):
    path, _, messages = recording
    report = salvage_mcap(path, tmp_path / "copy.mcap")
    assert report.stopped is None and sum(report.messages.values()) == len(messages) and report.dropped == 0
    assert _messages(tmp_path / "copy.mcap") == messages
    copy = RGBDMcapReader(tmp_path / "copy.mcap")
    assert copy.metadata == RGBDMcapReader(path).metadata
    assert all(_frames_equal(a, b) for a, b in zip(RGBDMcapReader(path), copy, strict=True))


def test_a_cut_recording_keeps_its_complete_chunks(recording, tmp_path):
    path, data, messages = recording
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    with pytest.raises(InputFileError, match=r"cut\.mcap: not a complete.*salvage_mcap\.py .*cut\.mcap <new file>"):
        RGBDMcapReader(cut)
    report = salvage_mcap(cut, tmp_path / "kept.mcap")
    assert "the file ends inside a record" in report.stopped
    kept = _messages(tmp_path / "kept.mcap")
    # Cut at 60% of the bytes: more than a third of the messages survive, and not all (the chunk it ends in is lost).
    assert len(messages) / 3 < len(kept) < len(messages) and kept == messages[: len(kept)]
    frames = list(RGBDMcapReader(tmp_path / "kept.mcap"))
    assert 3 <= len(frames) < 12
    originals = list(RGBDMcapReader(path))[: len(frames)]
    # The last kept frame may have lost its pose messages to the cut (the reader then takes the pose of
    # the frame before, SPEC 9 alignment): its images are the same, every earlier frame is the same.
    assert all(_frames_equal(a, b) for a, b in zip(frames[:-1], originals))
    assert np.array_equal(frames[-1].rgb, originals[-1].rgb) and frames[-1].t_s == originals[-1].t_s
    assert cut.read_bytes() == data[: int(len(data) * 0.6)]  # the damaged file is only read


def test_a_corrupt_chunk_stops_the_copy_there(recording, tmp_path):
    path, data, messages = recording
    broken = bytearray(data)
    middle = len(data) // 2
    broken[middle: middle + 64] = bytes(64)  # zeros over part of a chunk in the middle
    (tmp_path / "broken.mcap").write_bytes(bytes(broken))
    report = salvage_mcap(tmp_path / "broken.mcap", tmp_path / "kept.mcap")
    kept = _messages(tmp_path / "kept.mcap")
    assert report.stopped and 0 < len(kept) < len(messages) and kept == messages[: len(kept)]


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(fraction=st.floats(0.0, 1.0))
def test_any_cut_gives_a_prefix_or_a_clear_error(recording, tmp_path, fraction):
    """Wherever the file ends: a readable file of the first messages, or InputFileError and no file."""
    path, data, messages = recording
    cut, out = tmp_path / "cut.mcap", tmp_path / "out.mcap"
    out.unlink(missing_ok=True)
    cut.write_bytes(data[: int(len(data) * fraction)])
    try:
        salvage_mcap(cut, out)
    except InputFileError as error:
        assert "cut.mcap" in str(error) and not out.exists()
        return
    kept = _messages(out)
    assert kept and kept == messages[: len(kept)]


def test_bad_inputs_are_named_and_nothing_is_overwritten(recording, tmp_path):
    path, _, _ = recording
    text = tmp_path / "notes.mcap"
    text.write_text("not an MCAP file\n")
    with pytest.raises(InputFileError, match=r"notes\.mcap: not an MCAP file"):
        salvage_mcap(text, tmp_path / "a.mcap")
    with pytest.raises(InputFileError, match=r"absent\.mcap: no such file"):
        salvage_mcap(tmp_path / "absent.mcap", tmp_path / "b.mcap")
    with pytest.raises(InputFileError, match=r"another file than the one read"):
        salvage_mcap(path, path)
    header_only = tmp_path / "header.mcap"
    header_only.write_bytes(path.read_bytes()[:60])  # magic and header (43 bytes), then part of a record
    with pytest.raises(InputFileError, match=r"header\.mcap: no complete message"):
        salvage_mcap(header_only, tmp_path / "c.mcap")
    assert not (tmp_path / "a.mcap").exists() and not (tmp_path / "c.mcap").exists()
    existing = tmp_path / "existing.mcap"
    existing.write_bytes(b"keep me")
    with pytest.raises(StslamError, match="already exists"):
        salvage_mcap(path, existing)
    assert existing.read_bytes() == b"keep me"


def test_command_line(recording, tmp_path):
    path, _, messages = recording
    script = REPO / "experiments" / "salvage_mcap.py"
    done = subprocess.run([sys.executable, str(script), str(path), str(tmp_path / "out.mcap")],
                          capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    assert f"{len(messages)} messages" in done.stdout and "nothing was lost" in done.stdout
    again = subprocess.run([sys.executable, str(script), str(path), str(tmp_path / "out.mcap")],
                           capture_output=True, text=True, check=False)
    assert again.returncode == 2 and "--overwrite" in again.stderr and "Traceback" not in again.stderr
