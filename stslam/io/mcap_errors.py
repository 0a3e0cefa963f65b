"""What reading an MCAP file can raise, turned into one error that names the file (SPEC 9).

:func:`reading` wraps the mcap, zstandard and protobuf libraries' exceptions on
damaged input into one :class:`~stslam.errors.InputFileError` naming the file and
topic; the error of a file that begins as an MCAP adds how to salvage its
complete messages (:mod:`stslam.io.mcap_salvage`).
"""

from __future__ import annotations

import contextlib
import struct

import zstandard
from google.protobuf.message import DecodeError
from mcap.exceptions import McapError

from stslam.errors import InputFileError, StslamError

__all__ = ["LIBRARY_ERRORS", "MCAP_MAGIC", "ROSBAG1_MAGIC", "begins_as_mcap", "begins_with", "reading", "salvage_hint"]

# What the mcap, zstandard and protobuf libraries raise on damaged input.
LIBRARY_ERRORS = (McapError, struct.error, zstandard.ZstdError, DecodeError, UnicodeDecodeError, ValueError,
                  KeyError, IndexError, TypeError, AttributeError, EOFError, OverflowError, MemoryError, OSError,
                  RuntimeError)
MCAP_MAGIC = b"\x89MCAP0\r\n"
ROSBAG1_MAGIC = b"#ROSBAG V2.0"  # how a ROS 1 bag begins


def begins_with(path, magic: bytes) -> bool:
    """Whether the file at ``path`` begins with the bytes ``magic`` (False when it cannot be read)."""
    try:
        with open(path, "rb") as handle:
            return handle.read(len(magic)) == magic
    except OSError:
        return False


def begins_as_mcap(path) -> bool:
    """Whether the file at ``path`` begins with the MCAP magic bytes."""
    return begins_with(path, MCAP_MAGIC)


def salvage_hint(path) -> str:
    """What the error of a damaged or unfinished MCAP file adds (:mod:`stslam.io.mcap_salvage`); nothing
    for a file that does not even begin as one."""
    if not begins_as_mcap(path):
        return ""
    return f"; python experiments/salvage_mcap.py {path} <new file> keeps its complete messages"


@contextlib.contextmanager
def reading(path, topic: str | None = None):
    """Turn the libraries' exceptions into one InputFileError naming file and topic."""
    try:
        yield
    except StslamError:
        raise
    except LIBRARY_ERRORS as error:
        where = f"topic {topic}: " if topic else ""
        if isinstance(error, AttributeError):  # a damaged schema that lost a field of its Foxglove type
            raise InputFileError(path, f"{where}message has no field {error}: its schema is not the "
                                       f"Foxglove one of that name") from None
        text = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise InputFileError(path, f"{where}not a complete, readable MCAP file ({type(error).__name__}: "
                                   f"{text}){salvage_hint(path)}") from None
