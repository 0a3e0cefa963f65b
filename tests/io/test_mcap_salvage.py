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
    assert "runs past the end of the file" in report.stopped and report.damaged == report.unverified == 0
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


def _top_level(data: bytes) -> list[tuple[int, int, int]]:
    """(opcode, start, length) of each top-level record after the magic (MCAP: opcode byte, u64 length)."""
    out, at = [], 8
    while at + 9 <= len(data):
        length = int.from_bytes(data[at + 1: at + 9], "little")
        out.append((data[at], at, length))
        at += 9 + length
    return out


def _chunks(data: bytes) -> list[tuple[int, int]]:
    return [(start, length) for opcode, start, length in _top_level(data) if opcode == 0x06]  # 0x06: chunk


def _is_subsequence(part: list, whole: list) -> bool:
    rest = iter(whole)
    return all(any(item == other for other in rest) for item in part)


def test_a_corrupt_chunk_is_left_out_and_the_rest_kept(recording, tmp_path):
    path, data, messages = recording
    chunks = _chunks(data)
    assert len(chunks) >= 4, "the recording should span several chunks"
    start, length = chunks[len(chunks) // 2]
    broken = bytearray(data)
    middle = start + 9 + length // 2
    broken[middle: middle + 32] = bytes(32)  # zeros inside its compressed records: the checksum fails
    (tmp_path / "broken.mcap").write_bytes(bytes(broken))
    with pytest.raises(InputFileError, match=r"broken\.mcap: .*salvage_mcap\.py"):
        list(RGBDMcapReader(tmp_path / "broken.mcap"))
    report = salvage_mcap(tmp_path / "broken.mcap", tmp_path / "kept.mcap")
    kept = _messages(tmp_path / "kept.mcap")
    assert report.damaged == 1 and report.stopped is None and report.dropped == 0
    assert f"at byte {start}" in report.first_damage
    # Exactly one run of messages (the chunk's) is missing; everything before and after is kept.
    gap = next(i for i, (a, b) in enumerate(zip(kept, messages)) if a != b)
    missing = len(messages) - len(kept)
    assert missing > 0 and kept == messages[:gap] + messages[gap + missing:]


def test_a_damaged_length_ends_the_copy_or_is_never_trusted_after(recording, tmp_path):
    """A chunk's length too large for the file stops the copy there; one that fits but is wrong puts
    the reading off the boundaries, and then only checksummed chunks are kept."""
    path, data, messages = recording
    start, length = _chunks(data)[2]
    for name, new_length in (("long", len(data)), ("short", length // 2)):
        broken = bytearray(data)
        broken[start + 1: start + 9] = new_length.to_bytes(8, "little")
        (tmp_path / f"{name}.mcap").write_bytes(bytes(broken))
        report = salvage_mcap(tmp_path / f"{name}.mcap", tmp_path / f"{name}_kept.mcap")
        kept = _messages(tmp_path / f"{name}_kept.mcap")
        assert _is_subsequence(kept, messages) and len(kept) < len(messages)
        if name == "long":
            assert f"record at byte {start} runs past" in report.stopped and kept == messages[: len(kept)]
        else:
            assert report.damaged >= 1


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


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(where=st.floats(0.0, 1.0), width=st.integers(1, 64), value=st.integers(0, 255))
def test_no_damage_puts_a_wrong_message_in_the_copy(recording, tmp_path, where, width, value):
    """Bytes overwritten anywhere: the copy's messages are the original's in order with some left out,
    never one that was not there (chunks are checksummed), or a clear error and no file."""
    path, data, messages = recording
    broken, out = tmp_path / "broken.mcap", tmp_path / "out.mcap"
    out.unlink(missing_ok=True)
    at = int(where * (len(data) - 1))
    damaged = bytearray(data)
    damaged[at: at + width] = bytes([value]) * len(damaged[at: at + width])
    broken.write_bytes(bytes(damaged))
    try:
        salvage_mcap(broken, out)
    except InputFileError as error:
        assert "broken.mcap" in str(error) and not out.exists()
        return
    assert _is_subsequence(_messages(out), messages)


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


def test_an_unchunked_file_cut_short_keeps_its_first_messages(tmp_path):
    """Some writers put messages straight into the file, outside chunks (no checksums): cut anywhere, the
    copy holds the messages before the cut."""
    from mcap.writer import Writer

    path = tmp_path / "plain.mcap"
    with open(path, "wb") as handle:
        writer = Writer(handle, use_chunking=False)
        writer.start(profile="", library="test")
        channel = writer.register_channel("/t", "json", writer.register_schema("s", "jsonschema", b"{}"))
        for k in range(50):
            writer.add_message(channel, k * 1000, f'{{"k": {k}}}'.encode(), k * 1000, k)
        writer.finish()
    data, messages = path.read_bytes(), _messages(path)
    assert len(messages) == 50
    starts = [start for opcode, start, _ in _top_level(data) if opcode == 0x05]  # 0x05: message
    for k in (1, 20, 49):  # cut 5 bytes into message k: messages 0 … k − 1 are kept
        cut = tmp_path / f"cut{k}.mcap"
        cut.write_bytes(data[: starts[k] + 5])
        salvage_mcap(cut, tmp_path / f"kept{k}.mcap")
        assert _messages(tmp_path / f"kept{k}.mcap") == messages[:k]
