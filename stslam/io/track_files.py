"""Plain-text point tracks: reading a user's files and writing generated ones (SPEC 10).

Format, one observation per line:

    x y z                 or   x y z qx qy qz qw          (m; the position is used)
    t x y z               or   t x y z qx qy qz qw        (with ``time_column``; t in s)

Numbers are separated by whitespace and/or commas; ``#`` starts a comment
(whole line or the rest of a line). Header comments of the form
``# key: value`` are kept as metadata (generated tracks carry their ground
truth this way). Every row must have the same number of columns, every number
must be finite, positions within ±1e6 m, times must increase strictly, and there must be at least
``n_min`` rows; otherwise :class:`~stslam.errors.InputFileError` names the
file and (where there is one) the line. Numbers are plain decimal literals
(``-1.5``, ``.5``, ``2e-3``); Python-only forms such as ``1_000`` or non-ASCII
digits are rejected rather than silently read. A UTF-8 byte-order mark is
ignored; lines end with LF, CRLF or CR (the line numbers an editor shows).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from stslam.errors import InputFileError

_SEPARATORS = re.compile(r"[,\s]+")
_LINE_BREAKS = re.compile(r"\r\n|\r|\n")
# A decimal number, or a spelling of NaN/infinity (rejected below as not finite, with its line).
_NUMBER = re.compile(r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf|infinity)", re.IGNORECASE | re.ASCII)
# Positions are metres of a room or a building; a larger number is a unit or parsing error
# (and squares of it overflow in the fits).
MAX_COORDINATE_M = 1e6
_METADATA = re.compile(r"^#\s*([A-Za-z_][\w.]*)\s*:\s*(.*?)\s*$")


@dataclass(frozen=True)
class PointTrack:
    """A track read from a file.

    Attributes
    ----------
    path : str
    points_world : numpy.ndarray, shape (n, 3)
        Positions (m).
    times_s : numpy.ndarray or None, shape (n,)
        Times from the file's time column (s), or None.
    lines : numpy.ndarray, shape (n,)
        1-based line number of each observation.
    metadata : dict[str, str]
        ``# key: value`` header comments.
    """

    path: str
    points_world: np.ndarray
    times_s: np.ndarray | None
    lines: np.ndarray
    metadata: dict = field(default_factory=dict)


def parse_track_text(text: str, path: str, *, time_column: bool = False, n_min: int = 7) -> PointTrack:
    """Parse the text of a track file (see the module docstring); ``path`` is only used in errors."""
    widths = (4, 8) if time_column else (3, 7)
    rows, line_numbers, metadata = [], [], {}
    width = None
    for number, raw in enumerate(_LINE_BREAKS.split(text.removeprefix("\ufeff")), start=1):
        stripped = raw.strip()
        if stripped.startswith("#"):
            match = _METADATA.match(stripped)
            if match and not rows:
                metadata[match.group(1)] = match.group(2)
            continue
        content = stripped.split("#", 1)[0].strip().strip(",")
        if not content:
            continue
        fields = [f for f in _SEPARATORS.split(content) if f]
        if width is None:
            if len(fields) not in widths:
                raise InputFileError(path, f"expected {widths[0]} or {widths[1]} numbers per line "
                                           f"({'t ' if time_column else ''}x y z [qx qy qz qw]), "
                                           f"got {len(fields)}", number)
            width = len(fields)
        elif len(fields) != width:
            raise InputFileError(path, f"ragged rows: expected {width} numbers as on the first data line, "
                                       f"got {len(fields)}", number)
        bad = next((f for f in fields if not _NUMBER.fullmatch(f)), None)
        if bad is not None:
            raise InputFileError(path, f"not a number: {bad!r}", number)
        values = [float(f) for f in fields]
        if not all(np.isfinite(values)):
            raise InputFileError(path, "values must be finite (found NaN or infinity)", number)
        position = values[1:4] if time_column else values[:3]
        if max(abs(v) for v in position) > MAX_COORDINATE_M:
            raise InputFileError(path, f"a coordinate beyond ±{MAX_COORDINATE_M:g} m: {position!r}", number)
        rows.append(values)
        line_numbers.append(number)
    if not rows:
        raise InputFileError(path, "no observations (the file is empty or only has comments)")
    if len(rows) < n_min:
        raise InputFileError(path, f"{len(rows)} observations, fewer than N_min = {n_min} needed to fit a structure")
    data = np.array(rows)
    lines = np.array(line_numbers)
    times = None
    if time_column:
        times = data[:, 0]
        not_later = times[1:] <= times[:-1]  # compared, not subtracted: no overflow for huge times
        if np.any(not_later):
            i = int(np.argmax(not_later)) + 1
            raise InputFileError(path, f"time must increase strictly: {times[i]:g} s after {times[i - 1]:g} s",
                                 int(lines[i]))
        data = data[:, 1:]
    return PointTrack(path=str(path), points_world=data[:, :3].copy(), times_s=times, lines=lines,
                      metadata=metadata)


def read_track_file(path, *, time_column: bool = False, n_min: int = 7) -> PointTrack:
    """Read one track file; InputFileError for an unreadable or malformed file."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputFileError(path, "not a text file (not UTF-8)") from None
    except OSError as error:
        raise InputFileError(path, f"cannot be read: {error.strerror or error}") from None
    return parse_track_text(text, str(path), time_column=time_column, n_min=n_min)


def format_track(points_world, times_s=None, metadata: dict | None = None,
                 orientations_xyzw=None, separator: str = " ", row_comments=None) -> str:
    """Text of a track file: ``# key: value`` header lines, then one row per observation.

    ``orientations_xyzw`` (n, 4), if given, is written after the position
    (the 7- or 8-column form); numbers are joined by ``separator`` (a space, or
    ``","`` for a .csv); ``row_comments`` (n strings), if given, end each row as a ``# …`` comment.
    """
    points = np.asarray(points_world, dtype=float)
    columns = [points]
    if orientations_xyzw is not None:
        columns.append(np.asarray(orientations_xyzw, dtype=float))
    if times_s is not None:
        columns.insert(0, np.asarray(times_s, dtype=float)[:, None])
    table = np.hstack(columns)
    header = [f"# {key}: {value}" for key, value in (metadata or {}).items()]
    body = [separator.join(f"{v:.6f}" for v in row) for row in table]
    if row_comments is not None:
        body = [f"{row}  # {comment}" for row, comment in zip(body, row_comments, strict=True)]
    return "\n".join(header + body) + "\n"


def write_track_file(path, text: str) -> Path:
    """Write track text to ``path`` (parent folders are created)."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(text, encoding="utf-8")
    return target
