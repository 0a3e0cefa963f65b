"""Keep what is complete of a damaged or unfinished MCAP file, as a new complete file.

A recorder that crashes, is killed or loses power leaves an MCAP without its
summary and footer, usually cut inside a chunk; a copy broken off or a bad
disk block leaves a chunk whose checksum fails. :class:`~stslam.io.mcap_read.RGBDMcapReader`
needs the summary and refuses such a file. :func:`salvage_mcap` reads the file
record by record from the start and writes every schema, channel, message,
metadata and attachment record it meets to a new file with a summary. A
chunk counts whole or not at all. Messages are kept in file order with their
times, sequence numbers and bytes unchanged; the header's profile and
library string are kept.

Damage: a record whose length runs past the end of the file ends the copy (a
file cut short, or a damaged length field, after which nothing can be found
again). A record that is all there but does not read (a chunk whose checksum
or compression fails, a malformed record) is left out and the copy goes on
with the next; from then on, since a damaged length may have put the reading
off the records' boundaries, only chunks whose checksum holds are trusted, and
other records are left out (counted). Messages on a channel whose definition
was lost are left out (counted).

The new file is written under a temporary name and moved into place only
when complete (:func:`stslam.io.mcap_write.atomic_output`): an existing file
is replaced only with ``overwrite``, and the damaged file is never touched.
"""

from __future__ import annotations

import io
import os
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from mcap.data_stream import ReadDataStream
from mcap.exceptions import UnsupportedCompressionError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, DataEnd, Footer, Header, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from stslam.errors import InputFileError
from stslam.io.mcap_errors import LIBRARY_ERRORS, MCAP_MAGIC
from stslam.io.mcap_write import CHUNK_SIZE_BYTES, atomic_output

__all__ = ["SalvageReport", "salvage_mcap"]


@dataclass
class SalvageReport:
    """What :func:`salvage_mcap` kept.

    Attributes
    ----------
    source, target : pathlib.Path
    messages : collections.Counter
        Messages kept per topic.
    dropped : int
        Messages left out because their channel (or its schema) was never defined before them.
    damaged : int
        Records left out because they did not read (``first_damage`` says where and why the first).
    unverified : int
        Records without a checksum left out after the first damaged one.
    unknown : int
        Records of an opcode MCAP does not define, skipped (a later version's, or a damaged opcode).
    first_ns, last_ns : int or None
        Smallest and largest log time kept (ns).
    stopped : str or None
        Why reading stopped before the file's end (a record running past it, or a chunk compressed in a
        way this machine cannot read); None when the whole file was read.
    """

    source: Path
    target: Path
    messages: Counter = field(default_factory=Counter)
    dropped: int = 0
    damaged: int = 0
    first_damage: str | None = None
    unverified: int = 0
    unknown: int = 0
    first_ns: int | None = None
    last_ns: int | None = None
    stopped: str | None = None

    def lines(self) -> list[str]:
        """The report as printed lines."""
        total = sum(self.messages.values())
        span = ("" if self.first_ns is None else
                f", log times {self.first_ns / 1e9:.3f}–{self.last_ns / 1e9:.3f} s")
        lines = [f"{self.target}: {total} messages from {self.source}{span}"]
        lines += [f"  {topic}: {count}" for topic, count in sorted(self.messages.items())]
        if self.damaged:
            lines.append(f"  left out: {self.damaged} damaged records (the first {self.first_damage})")
        if self.unverified:
            lines.append(f"  left out: {self.unverified} records without a checksum after the damage")
        if self.unknown:
            lines.append(f"  skipped: {self.unknown} records of kinds MCAP does not define")
        if self.dropped:
            lines.append(f"  left out: {self.dropped} messages on channels defined nowhere before them")
        if self.stopped:
            lines.append(f"  stopped: {self.stopped}")
        elif not (self.damaged or self.unverified or self.unknown or self.dropped):
            lines.append("  the whole file was readable: nothing was lost")
        return lines


class _Copier:
    """Records of one source file into an MCAP writer, with the source's ids mapped to the writer's."""

    def __init__(self, writer: McapWriter, report: SalvageReport):
        self.writer = writer
        self.report = report
        self.schemas: dict[int, int] = {0: 0}  # source schema id → target id; 0 is "no schema"
        self.channels: dict[int, tuple[int, str]] = {}  # source channel id → (target id, topic)

    def add(self, record) -> None:
        if isinstance(record, Schema) and record.id not in self.schemas:
            self.schemas[record.id] = self.writer.register_schema(record.name, record.encoding, record.data)
        elif isinstance(record, Channel) and record.id not in self.channels and record.schema_id in self.schemas:
            target = self.writer.register_channel(record.topic, record.message_encoding,
                                                  self.schemas[record.schema_id], dict(record.metadata))
            self.channels[record.id] = (target, record.topic)
        elif isinstance(record, Message):
            self._message(record)
        elif isinstance(record, Metadata):
            self.writer.add_metadata(record.name, dict(record.metadata))
        elif isinstance(record, Attachment):
            self.writer.add_attachment(record.create_time, record.log_time, record.name, record.media_type,
                                       record.data)

    def _message(self, record: Message) -> None:
        if record.channel_id not in self.channels:
            self.report.dropped += 1
            return
        target, topic = self.channels[record.channel_id]
        self.writer.add_message(target, record.log_time, record.data, record.publish_time, record.sequence)
        report = self.report
        report.messages[topic] += 1
        report.first_ns = record.log_time if report.first_ns is None else min(report.first_ns, record.log_time)
        report.last_ns = record.log_time if report.last_ns is None else max(report.last_ns, record.log_time)


_RECORD_HEAD = 9  # opcode (1 byte) and length (8 bytes, little-endian)
# Records the copy has no use for, after DataEnd or anywhere: never counted as left out.
_UNUSED = {Opcode.DATA_END, Opcode.FOOTER, Opcode.MESSAGE_INDEX, Opcode.CHUNK_INDEX, Opcode.ATTACHMENT_INDEX,
           Opcode.METADATA_INDEX, Opcode.STATISTICS, Opcode.SUMMARY_OFFSET}
_READERS = {Opcode.HEADER: Header.read, Opcode.SCHEMA: Schema.read, Opcode.CHANNEL: Channel.read,
            Opcode.METADATA: Metadata.read, Opcode.ATTACHMENT: Attachment.read, Opcode.DATA_END: DataEnd.read,
            Opcode.FOOTER: Footer.read}


class _UnknownRecord(Exception):
    """A record of an opcode this version of MCAP does not define (skipped, as MCAP readers do)."""


def _describe(error: Exception) -> str:
    text = str(error).splitlines()[0] if str(error) else ""
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def _parse(opcode: int, body: bytes, checked_only: bool) -> list | None:
    """The records of one top-level record (a chunk's, unpacked), or None when it is not to be trusted."""
    stream = ReadDataStream(io.BytesIO(body))
    if opcode == Opcode.CHUNK:
        chunk = Chunk.read(stream)
        if checked_only and chunk.uncompressed_crc == 0:
            return None
        return breakup_chunk(chunk, validate_crc=True)
    if opcode == Opcode.MESSAGE:
        return None if checked_only else [Message.read(stream, len(body))]
    if opcode not in _READERS and opcode not in _UNUSED:
        raise _UnknownRecord(opcode)
    if opcode in _READERS and (opcode in _UNUSED or not checked_only):
        return [_READERS[opcode](stream)]
    return [] if opcode in _UNUSED else None


def _records(handle, size: int, report: SalvageReport):
    """The file's records in order after the magic, a chunk's one by one; what cannot be read goes into
    ``report`` (module docstring)."""
    damaged = False
    while True:
        start = handle.tell()
        head = handle.read(_RECORD_HEAD)
        if not head:
            return
        length = int.from_bytes(head[1:], "little") if len(head) == _RECORD_HEAD else None
        if length is None or length > size - start - _RECORD_HEAD:
            report.stopped = (f"the record at byte {start} runs past the end of the file (a file cut short, or "
                              f"a damaged length field)")
            return
        opcode, body = head[0], handle.read(length)
        try:
            records = _parse(opcode, body, damaged)
        except _UnknownRecord:  # after damage, more likely bytes read off the records' boundaries
            report.unverified += damaged
            report.unknown += not damaged
            continue
        except UnsupportedCompressionError as error:
            report.stopped = f"the chunk at byte {start}: {_describe(error)}"
            return
        except LIBRARY_ERRORS as error:
            damaged = True
            report.damaged += 1
            report.first_damage = report.first_damage or f"at byte {start}: {_describe(error)}"
            continue
        if records is None:
            report.unverified += 1
            continue
        yield from records
        if opcode in (Opcode.DATA_END, Opcode.FOOTER):  # what follows DataEnd is the summary: copies and indexes
            return


def salvage_mcap(source, target, *, overwrite: bool = False) -> SalvageReport:
    """Copy the complete records of the MCAP file ``source`` into a new MCAP file ``target``.

    Raises :class:`~stslam.errors.InputFileError` (naming ``source``) when it is missing, does not
    begin as an MCAP file, or holds no complete message; ``target`` is then not written.
    """
    source, target = Path(source), Path(target)
    if not source.is_file():
        raise InputFileError(source, "no such file")
    if target.resolve() == source.resolve():
        raise InputFileError(source, "the new file must be another file than the one read")
    report = SalvageReport(source=source, target=target)
    with open(source, "rb") as handle:
        if handle.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise InputFileError(source, "not an MCAP file: it does not begin with the MCAP magic bytes")
        records = _records(handle, os.path.getsize(source), report)
        first = next(records, None)
        if not isinstance(first, Header):
            raise InputFileError(source, f"not an MCAP file: no header after the magic bytes "
                                         f"({report.stopped or report.first_damage or type(first).__name__})")
        with atomic_output(target, overwrite) as out:
            writer = McapWriter(out, chunk_size=CHUNK_SIZE_BYTES, compression=CompressionType.ZSTD)
            writer.start(profile=first.profile, library=first.library)
            copier = _Copier(writer, report)
            for record in records:
                copier.add(record)
            if not report.messages:
                why = report.stopped or report.first_damage or "it holds none"
                raise InputFileError(source, f"no complete message to keep ({why})")
            writer.finish()
    return report

