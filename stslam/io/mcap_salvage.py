"""Keep what is complete of a damaged or unfinished MCAP file, as a new complete file.

A recorder that crashes, is killed or loses power leaves an MCAP without its
summary and footer, usually cut inside a chunk; a copy broken off or a bad
disk block leaves a chunk whose checksum fails. :class:`~stslam.io.mcap_read.RGBDMcapReader`
needs the summary and refuses such a file. :func:`salvage_mcap` reads the file
record by record from the start (checksums checked) and writes every schema,
channel, message, metadata and attachment record it meets to a new file with
a summary, up to the first record it cannot read; a chunk counts whole or not
at all. Messages are kept in file order with their times, sequence numbers
and bytes unchanged; the header's profile and library string are kept.

The new file is written under a temporary name and moved into place only
when complete (:func:`stslam.io.mcap_write.atomic_output`): an existing file
is replaced only with ``overwrite``, and the damaged file is never touched.
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import EndOfFile, RecordLengthLimitExceeded
from mcap.records import Attachment, Channel, DataEnd, Header, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType
from mcap.writer import Writer as McapWriter

from stslam.errors import InputFileError
from stslam.io.mcap_errors import LIBRARY_ERRORS
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
    first_ns, last_ns : int or None
        Smallest and largest log time kept (ns).
    stopped : str or None
        Why reading stopped before the file's end (the first unreadable record); None when the
        whole file was read.
    """

    source: Path
    target: Path
    messages: Counter = field(default_factory=Counter)
    dropped: int = 0
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
        if self.dropped:
            lines.append(f"  left out: {self.dropped} messages on channels defined nowhere before them")
        lines.append(f"  stopped at the first unreadable record: {self.stopped}" if self.stopped
                     else "  the whole file was readable: nothing was lost")
        return lines


class _Copier:
    """Records of one source file into an MCAP writer, with the source's ids mapped to the writer's."""

    def __init__(self, writer: McapWriter, report: SalvageReport):
        self.writer = writer
        self.report = report
        self.schemas: dict[int, int] = {0: 0}  # source schema id → target id; 0 is "no schema"
        self.channels: dict[int, tuple[int, str]] = {}  # source channel id → (target id, topic)
        self.data_ended = False

    def add(self, record) -> None:
        if isinstance(record, DataEnd):
            self.data_ended = True  # what follows is the summary: copies of schemas and channels
        elif self.data_ended:
            return
        elif isinstance(record, Schema) and record.id not in self.schemas:
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


def _records(handle, size: int):
    """The file's records in order, then ``None`` and the reason if one could not be read."""
    # No record can be longer than the file: a damaged length field fails fast instead of allocating.
    records = iter(StreamReader(handle, validate_crcs=True, record_size_limit=max(1, size)).records)
    while True:
        try:
            record = next(records)
        except StopIteration:
            return
        except LIBRARY_ERRORS as error:
            text = f"{type(error).__name__}: {str(error).splitlines()[0]}" if str(error) else type(error).__name__
            if isinstance(error, (EndOfFile, RecordLengthLimitExceeded)):  # the length runs past the file's end
                text = f"the file ends inside a record, or its length field is damaged ({text})"
            yield None, text
            return
        yield record, None


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
        records = _records(handle, os.path.getsize(source))
        first, problem = next(records, (None, "empty file"))
        if not isinstance(first, Header):
            raise InputFileError(source, f"not an MCAP file: it does not begin with the MCAP magic and header "
                                         f"({problem or type(first).__name__})")
        with atomic_output(target, overwrite) as out:
            writer = McapWriter(out, chunk_size=CHUNK_SIZE_BYTES, compression=CompressionType.ZSTD)
            writer.start(profile=first.profile, library=first.library)
            copier = _Copier(writer, report)
            for record, problem in records:
                if record is None:
                    report.stopped = problem
                    break
                copier.add(record)
            if not report.messages:
                raise InputFileError(source, f"no complete message to keep (stopped: {report.stopped or 'no messages'})")
            writer.finish()
    return report

