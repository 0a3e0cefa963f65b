"""Read a user's motion-variable trace from CSV (SPEC 8.2).

Format: a header row, then one sample per row, with either the columns
``t,angle`` (time in s, angle in rad; any column order) or the single column
``angle`` (samples every δt, given by the caller). Blank lines are skipped.
Every problem raises :class:`~stslam.errors.InputFileError` naming the file
and, where it sits on one line, the 1-based line number.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from stslam.errors import InputFileError

ACCEPTED_HEADERS = ({"t", "angle"}, {"angle"})


def _number(path, text: str, line: int, column: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise InputFileError(path, f"column {column!r}: expected a number, got {text.strip()!r}", line) from None
    if not math.isfinite(value):
        raise InputFileError(path, f"column {column!r}: expected a finite number, got {text.strip()!r}", line)
    return value


def read_angle_trace(path, dt: float | None = None, min_rows: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Times (s) and angles (rad) of a trace file.

    Parameters
    ----------
    path : str or Path
        CSV file with a header ``t,angle`` or ``angle``.
    dt : float, optional
        Sample spacing (s) for a file without a ``t`` column (times 0, δt, 2δt, …).
    min_rows : int
        Fewest data rows accepted (the filter's initialisation window plus one).

    Returns
    -------
    times : numpy.ndarray, shape (n,)
        Strictly increasing (s).
    angles : numpy.ndarray, shape (n,)
        Angles (rad).

    Raises
    ------
    InputFileError
        Unreadable or empty file, a header other than ``t,angle`` / ``angle``,
        a row with the wrong number of cells, a cell that is not a finite
        number, times that do not increase, fewer than ``min_rows`` rows, or a
        file without ``t`` when ``dt`` is not given.
    """
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            rows = [(number, row) for number, row in enumerate(csv.reader(handle), start=1)]
    except OSError as error:  # strerror alone: the message already starts with the path
        raise InputFileError(path, f"cannot read the file: {error.strerror or error}") from None
    except UnicodeDecodeError as error:
        raise InputFileError(path, f"cannot read the file: not UTF-8 text (byte {error.start})") from None
    except csv.Error as error:
        raise InputFileError(path, f"cannot read the file: {error}") from None
    rows = [(number, row) for number, row in rows if any(cell.strip() for cell in row)]
    if not rows:
        raise InputFileError(path, "empty file: expected a header row 't,angle' or 'angle'")
    header_line, header = rows[0]
    names = [cell.strip().lower() for cell in header]
    if len(set(names)) != len(names) or set(names) not in ACCEPTED_HEADERS:
        missing = sorted({"angle"} - set(names))
        problem = f"missing column {missing[0]!r}" if missing else "unexpected columns"
        raise InputFileError(path, f"{problem} in header {','.join(header)!r}: expected 't,angle' or 'angle'",
                             header_line)
    has_time = "t" in names
    if not has_time and (dt is None or not dt > 0):
        raise InputFileError(path, f"no 't' column and no time step dt > 0 given (dt={dt!r})")
    data = rows[1:]
    angle_col = names.index("angle")
    time_col = names.index("t") if has_time else None
    times, angles = np.empty(len(data)), np.empty(len(data))
    for i, (line, row) in enumerate(data):
        if len(row) != len(names):
            raise InputFileError(path, f"expected {len(names)} cells as in the header, got {len(row)}", line)
        angles[i] = _number(path, row[angle_col], line, "angle")
        if has_time:
            times[i] = _number(path, row[time_col], line, "t")
            if i > 0 and times[i] <= times[i - 1]:
                raise InputFileError(path, f"time {float(times[i])!r} does not increase "
                                           f"(previous row: {float(times[i - 1])!r})", line)
    if len(data) < min_rows:
        raise InputFileError(path, f"{len(data)} data rows: expected at least {min_rows} "
                                   "(the initialisation window plus one)")
    if not has_time:
        times = dt * np.arange(len(data), dtype=float)
    return times, angles
