"""Property tests of the track-file reader (issue 12, SPEC 10): random bytes and mutated
valid files either load, and then satisfy the reader's documented invariants, or raise
:class:`~stslam.errors.InputFileError` whose message starts with the path. Any other
exception (a traceback from deep in numpy or the float parser) fails the test.

Reader: :func:`stslam.io.track_files.read_track_file` (and :func:`parse_track_text`, which it calls).
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stslam.errors import InputFileError
from stslam.io.track_files import format_track, parse_track_text, read_track_file

# Each example writes one small file; 150 examples per property keep the file at a few seconds.
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow],
                derandomize=True)

# Cells a user's file may hold where a number belongs: non-finite spellings, overflow, text,
# Python-only literals (underscores, non-ASCII digits) and control characters.
NON_FINITE_CELLS = ("nan", "NaN", "inf", "-inf", "Infinity", "1e999", "-1e999")
TEXT_CELLS = ("abc", "0x10", "1_000", "１", "\x00", '"', "1.2.3", "e5", "--1", "½")
WIDTHS = {False: (3, 7), True: (4, 8)}  # per time_column: position only, or position and quaternion

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """A folder reused by every example (Hypothesis cannot use function-scoped tmp_path)."""
    return tmp_path_factory.mktemp("fuzz")


def _write(folder, data: bytes):
    path = folder / "track.txt"
    path.write_bytes(data)
    return path


# --- valid files and their mutations ------------------------------------------------------

@st.composite
def valid_rows(draw, time_column: bool, min_size: int = 0):
    """Cells (repr strings, exact float64 round trip) of a valid track: 3 or 7 numbers per row,
    with a strictly increasing leading time (s) when ``time_column``."""
    width = draw(st.sampled_from(WIDTHS[time_column]))
    n = draw(st.integers(min_value=min_size, max_value=12))
    rows = [[repr(v) for v in draw(st.lists(finite, min_size=width, max_size=width))] for _ in range(n)]
    if time_column and n:
        steps = draw(st.lists(st.floats(min_value=1e-3, max_value=10.0), min_size=n, max_size=n))
        times = draw(st.floats(min_value=-100.0, max_value=100.0)) + np.cumsum(steps)
        for row, t in zip(rows, times):
            row[0] = repr(float(t))
    return rows


@st.composite
def layout(draw, rows):
    """Text lines of ``rows`` with a random separator, ``# key: value`` header, comment lines,
    trailing comments and blank lines; returns (lines, 1-based line number of each row, header)."""
    separator = draw(st.sampled_from([" ", ",", ", ", "\t", "  ", " ,"]))
    header = draw(st.dictionaries(st.sampled_from(["true_model", "onset_s", "kind"]),
                                  st.sampled_from(["revolute", "0.5", "door"]), max_size=2))
    lines = [f"# {key}: {value}" for key, value in header.items()]
    numbers = []
    for row in rows:
        for _ in range(draw(st.integers(min_value=0, max_value=1))):
            lines.append(draw(st.sampled_from(["", "   ", "# a comment", "#", ",,"])))
        text = separator.join(row)
        if draw(st.integers(min_value=0, max_value=4)) == 0:
            text += draw(st.sampled_from(["  # trailing comment", "#x", ","]))
        lines.append(text)
        numbers.append(len(lines))
    return lines, numbers, header


def _encode(lines, newline: str, bom: bool) -> bytes:
    return (b"\xef\xbb\xbf" if bom else b"") + (newline.join(lines) + newline).encode("utf-8")


@st.composite
def mutated_file(draw):
    """(bytes, time_column) of a valid track after a random sequence of mutations.

    Row level: a number replaced by a bad cell, a cell added or removed (ragged row; 3↔4 and
    7↔8 columns look like the other time-column setting), two rows swapped (time out of
    order), a duplicated row (equal times), the file read with the other ``time_column``;
    then the byte level: BOM, CRLF or CR line ends, truncation at a random byte.
    """
    time_column = draw(st.booleans())
    rows = [list(r) for r in draw(valid_rows(time_column))]
    for _ in range(draw(st.integers(min_value=0, max_value=3))):
        if not rows:
            break
        i = draw(st.integers(min_value=0, max_value=len(rows) - 1))
        kind = draw(st.sampled_from(["bad_cell", "extra_cell", "drop_cell", "swap", "duplicate"]))
        if kind == "bad_cell":
            j = draw(st.integers(min_value=0, max_value=len(rows[i]) - 1))
            rows[i][j] = draw(st.sampled_from(NON_FINITE_CELLS + TEXT_CELLS))
        elif kind == "extra_cell":
            rows[i].append(draw(st.sampled_from(("0.5", "x", "1.0"))))
        elif kind == "drop_cell":
            rows[i].pop()
        elif kind == "swap":
            k = draw(st.integers(min_value=0, max_value=len(rows) - 1))
            rows[i], rows[k] = rows[k], rows[i]
        elif kind == "duplicate":
            rows.insert(i, list(rows[i]))
    lines, _, _ = draw(layout([r for r in rows if r]))
    data = _encode(lines, draw(st.sampled_from(["\n", "\r\n", "\r"])), draw(st.booleans()))
    if draw(st.booleans()) and data:
        data = data[:draw(st.integers(min_value=0, max_value=len(data)))]
    read_with_time = time_column if draw(st.integers(min_value=0, max_value=3)) else not time_column
    return data, read_with_time


arbitrary_bytes = st.binary(max_size=400)
arbitrary_text = st.text(alphabet=st.characters(codec="utf-8"), max_size=300).map(lambda s: s.encode("utf-8"))
numeric_soup = st.lists(st.sampled_from(["0", "1.5", "-2", "3e-2", " ", ",", "\t", "\n", "\r\n", "\r", "nan",
                                         "1e999", "#", "# k: v", "\ufeff", "\x0c", "\u2028", "x"]),
                        max_size=80).map(lambda p: "".join(p).encode("utf-8"))


# --- properties ---------------------------------------------------------------------------

def _check(path, time_column: bool, n_min: int):
    """Load or raise InputFileError naming the path; a loaded track satisfies the module docstring."""
    try:
        track = read_track_file(path, time_column=time_column, n_min=n_min)
    except InputFileError as error:
        assert str(error).startswith(f"{path}:"), str(error)
        assert error.path == str(path)
        return
    n = track.points_world.shape[0]
    assert track.points_world.shape == (n, 3) and track.points_world.dtype == float
    assert n >= max(n_min, 1)
    assert np.all(np.isfinite(track.points_world))
    assert track.lines.shape == (n,) and track.lines[0] >= 1 and np.all(np.diff(track.lines) > 0)
    if time_column:
        assert track.times_s.shape == (n,)
        assert np.all(np.isfinite(track.times_s)) and np.all(track.times_s[1:] > track.times_s[:-1])
    else:
        assert track.times_s is None


@FUZZ
@given(data=st.one_of(arbitrary_bytes, arbitrary_text, numeric_soup), time_column=st.booleans(),
       n_min=st.integers(min_value=0, max_value=4))
def test_random_bytes_load_or_raise_input_file_error(scratch, data, time_column, n_min):
    _check(_write(scratch, data), time_column, n_min)


@FUZZ
@given(case=mutated_file(), n_min=st.integers(min_value=0, max_value=7))
def test_mutated_files_load_or_raise_input_file_error(scratch, case, n_min):
    data, time_column = case
    _check(_write(scratch, data), time_column, n_min)


@FUZZ
@given(data=st.data(), time_column=st.booleans(), newline=st.sampled_from(["\n", "\r\n", "\r"]),
       bom=st.booleans())
def test_valid_file_loads_the_numbers_written_on_their_lines(scratch, data, time_column, newline, bom):
    """Unmutated files load exactly (repr round-trips float64) and each row keeps its line number."""
    rows = data.draw(valid_rows(time_column, min_size=1))
    lines, numbers, header = data.draw(layout(rows))
    track = read_track_file(_write(scratch, _encode(lines, newline, bom)), time_column=time_column, n_min=1)
    table = np.array([[float(c) for c in r] for r in rows])
    first = 1 if time_column else 0
    np.testing.assert_array_equal(track.points_world, table[:, first:first + 3])
    np.testing.assert_array_equal(track.lines, numbers)
    if time_column:
        np.testing.assert_array_equal(track.times_s, table[:, 0])
    assert track.metadata == header


@FUZZ
@given(data=st.data(), time_column=st.booleans(), cell=st.sampled_from(NON_FINITE_CELLS + TEXT_CELLS))
def test_one_bad_cell_is_reported_on_its_line(scratch, data, time_column, cell):
    """A single bad number in an otherwise valid file: the error names that file line."""
    rows = data.draw(valid_rows(time_column, min_size=1))
    lines, numbers, _ = data.draw(layout(rows))
    i = data.draw(st.integers(min_value=0, max_value=len(rows) - 1))
    j = data.draw(st.integers(min_value=0, max_value=len(rows[i]) - 1))
    row = list(rows[i])
    row[j] = cell
    lines[numbers[i] - 1] = " ".join(row)
    path = _write(scratch, _encode(lines, "\n", False))
    problem = "values must be finite" if cell in NON_FINITE_CELLS else "not a number"
    with pytest.raises(InputFileError, match=f"^{re.escape(str(path))}:{numbers[i]}: {problem}"):
        read_track_file(path, time_column=time_column, n_min=1)


def test_format_track_round_trips_through_the_reader(tmp_path):
    """The writer's 6-decimal text reads back to the rounded values, with its metadata (all four widths)."""
    rng = np.random.default_rng(5)
    points = rng.normal(size=(9, 3))
    times = np.cumsum(rng.uniform(0.01, 0.1, 9))
    quats = rng.normal(size=(9, 4))
    for with_time in (False, True):
        for orientations in (None, quats):
            text = format_track(points, times if with_time else None, {"true_model": "drawer"}, orientations)
            path = tmp_path / "t.txt"
            path.write_text(text)
            track = read_track_file(path, time_column=with_time)
            # %.6f rounds to 5e-7 at most; the parsed decimal is the nearest float64 to it.
            np.testing.assert_allclose(track.points_world, points, rtol=0, atol=5e-7 + 1e-15)
            assert track.metadata == {"true_model": "drawer"}
            if with_time:
                np.testing.assert_allclose(track.times_s, times, rtol=0, atol=5e-7 + 1e-15)


@pytest.mark.parametrize("text, time_column, message", [
    ("\ufeff" + "\n".join(f"{i} 0 1" for i in range(3)), False, None),          # BOM ignored
    ("\n".join(f"{i} 1_0 1" for i in range(3)), False, r":1: not a number: '1_0'"),  # float() would say 10
    ("\n".join(f"{i} ١ 1" for i in range(3)), False, r":1: not a number: '١'"),     # Arabic-Indic digit
    ("0 0 0\x0c1 1 1\n2 2 2\n", False, r":1: expected 3 or 7 numbers per line"),    # form feed is not a line end
    ("-1e308 0 0 0\n1e308 1 1 1\n1.5e308 2 2 2\n", True, None),                    # huge times: no overflow
    ("0 0 0 0\n1 1 1 1\n1 2 2 2\n", True, r":3: time must increase strictly: 1 s after 1 s"),
])
def test_edge_cases(text, time_column, message):
    if message is None:
        track = parse_track_text(text, "e.txt", time_column=time_column, n_min=3)
        assert track.points_world.shape == (3, 3) and np.all(np.isfinite(track.points_world))
        return
    with pytest.raises(InputFileError, match=r"^e\.txt" + message):
        parse_track_text(text, "e.txt", time_column=time_column, n_min=3)


def test_missing_file_folder_and_undecodable_bytes(tmp_path):
    missing = tmp_path / "missing.txt"
    with pytest.raises(InputFileError, match=f"^{re.escape(str(missing))}: cannot be read: No such file"):
        read_track_file(missing)
    with pytest.raises(InputFileError, match=f"^{re.escape(str(tmp_path))}: cannot be read: Is a directory"):
        read_track_file(tmp_path)
    path = _write(tmp_path, b"0 0 0\n\xff\xfe 1 1\n")
    with pytest.raises(InputFileError, match=f"^{re.escape(str(path))}: not a text file"):
        read_track_file(path)
