"""Property tests of the user-file readers (issue 12, SPEC 12): random and mutated files
either load, and then satisfy the reader's documented invariants, or raise
:class:`~stslam.errors.InputFileError` whose message starts with the path. Any
other exception (a traceback from deep in numpy or csv) fails the test.

Readers: :func:`stslam.io.trace_csv.read_angle_trace` (SPEC 8.2) and
:func:`stslam.io.tum.read_tum` (SPEC 7).
"""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stslam.errors import InputFileError
from stslam.io.trace_csv import read_angle_trace
from stslam.io.tum import format_tum, read_tum

# Each example writes one small file; 150 examples per property keep the file at a few seconds.
FUZZ = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow],
                derandomize=True)

# Cells a user's file may contain where a number belongs.
BAD_CELLS = ("nan", "NaN", "inf", "-inf", "1e999", "", " ", "abc", "0x10", "1,5", '"', "\x00", "∞", "1e-400")


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """A folder reused by every example (Hypothesis cannot use function-scoped tmp_path)."""
    return tmp_path_factory.mktemp("fuzz")


def _write(folder, data: bytes):
    path = folder / "input.txt"
    path.write_bytes(data)
    return path


# --- valid files and their mutations ------------------------------------------------------

finite = st.floats(min_value=-1e6, max_value=1e6, allow_nan=False, allow_infinity=False)


@st.composite
def valid_trace_rows(draw):
    """Header cells and data rows of a valid trace: t,angle (any order) or angle only."""
    layout = draw(st.sampled_from([("t", "angle"), ("angle", "t"), ("angle",)]))
    n = draw(st.integers(min_value=0, max_value=12))
    steps = draw(st.lists(st.floats(min_value=1e-3, max_value=10.0), min_size=n, max_size=n))
    t0 = draw(st.floats(min_value=-100.0, max_value=100.0))
    times = t0 + np.cumsum(steps) if n else np.empty(0)
    angles = draw(st.lists(finite, min_size=n, max_size=n))
    rows = [[repr(float(times[i])) if name == "t" else repr(angles[i]) for name in layout] for i in range(n)]
    return list(layout), rows


@st.composite
def valid_tum_rows(draw):
    """Rows of a valid TUM file (8 numbers each), possibly with comment lines."""
    n = draw(st.integers(min_value=0, max_value=8))
    rows = [[repr(v) for v in draw(st.lists(finite, min_size=8, max_size=8))] for _ in range(n)]
    return rows


@st.composite
def mutated(draw, rows_strategy, with_header: bool):
    """Text of a valid file after a random sequence of mutations, as bytes.

    Mutations: a number replaced by a bad cell, a cell added or removed (ragged
    row), two rows swapped (time out of order), empty lines, a duplicated row,
    then the byte level: BOM, CRLF, truncation at a random byte.
    """
    if with_header:
        header, rows = draw(rows_strategy)
    else:
        header, rows = None, draw(rows_strategy)
    rows = [list(r) for r in rows]
    for _ in range(draw(st.integers(min_value=0, max_value=3))):
        if not rows:
            break
        i = draw(st.integers(min_value=0, max_value=len(rows) - 1))
        kind = draw(st.sampled_from(["bad_cell", "extra_cell", "drop_cell", "swap", "blank", "duplicate"]))
        if kind == "bad_cell":
            j = draw(st.integers(min_value=0, max_value=len(rows[i]) - 1)) if rows[i] else 0
            rows[i][j:j + 1] = [draw(st.sampled_from(BAD_CELLS))]
        elif kind == "extra_cell":
            rows[i].append(draw(st.sampled_from(("0.5", "x", ""))))
        elif kind == "drop_cell" and rows[i]:
            rows[i].pop()
        elif kind == "swap":
            k = draw(st.integers(min_value=0, max_value=len(rows) - 1))
            rows[i], rows[k] = rows[k], rows[i]
        elif kind == "blank":
            rows.insert(i, [])
        elif kind == "duplicate":
            rows.insert(i, list(rows[i]))
    separator = draw(st.sampled_from([",", " "])) if header is None else ","
    lines = ([",".join(header)] if header is not None else []) + [separator.join(r) for r in rows]
    if header is None and draw(st.booleans()):
        lines.insert(0, "# timestamp tx ty tz qx qy qz qw")
    newline = draw(st.sampled_from(["\n", "\r\n", "\r"]))
    data = (newline.join(lines) + newline).encode("utf-8")
    if draw(st.booleans()):
        data = b"\xef\xbb\xbf" + data
    if draw(st.booleans()) and data:
        data = data[:draw(st.integers(min_value=0, max_value=len(data)))]
    return data


arbitrary_bytes = st.binary(max_size=300)
arbitrary_text = st.text(alphabet=st.characters(codec="utf-8"), max_size=200).map(lambda s: s.encode("utf-8"))
numeric_soup = st.lists(st.sampled_from(["t", "angle", ",", "\n", "\r\n", "0", "1.5", "-2", "nan", "1e999",
                                         " ", "\ufeff", '"', "#"]), max_size=60).map(lambda p: "".join(p).encode())


# --- read_angle_trace -------------------------------------------------------------------------

def _check_trace(path, dt, min_rows):
    """Load or raise InputFileError naming the path; a loaded trace satisfies the docstring."""
    try:
        times, angles = read_angle_trace(path, dt=dt, min_rows=min_rows)
    except InputFileError as error:
        assert str(error).startswith(str(path)), str(error)
        return
    assert times.shape == angles.shape == (times.size,)
    assert times.size >= min_rows
    assert np.all(np.isfinite(times)) and np.all(np.isfinite(angles))
    assert np.all(np.diff(times) > 0)


trace_inputs = st.one_of(arbitrary_bytes, arbitrary_text, numeric_soup, mutated(valid_trace_rows(), True))
dts = st.one_of(st.none(), st.floats(min_value=1e-3, max_value=100.0))


@FUZZ
@given(data=trace_inputs, dt=dts, min_rows=st.integers(min_value=1, max_value=6))
def test_trace_reader_loads_or_raises_input_file_error(scratch, data, dt, min_rows):
    _check_trace(_write(scratch, data), dt, min_rows)


@FUZZ
@given(rows=valid_trace_rows(), bom=st.booleans(), newline=st.sampled_from(["\n", "\r\n"]))
def test_valid_trace_round_trips_exactly(scratch, rows, bom, newline):
    """Unmutated files load to the numbers written (repr round-trips float64 exactly)."""
    header, body = rows
    text = newline.join([",".join(header)] + [",".join(r) for r in body]) + newline
    path = _write(scratch, (b"\xef\xbb\xbf" if bom else b"") + text.encode())
    if not body:
        with pytest.raises(InputFileError, match="0 data rows: expected at least 1"):
            read_angle_trace(path, dt=1.0, min_rows=1)
        return
    times, angles = read_angle_trace(path, dt=0.5, min_rows=1)
    expected = np.array([[float(c) for c in r] for r in body])
    np.testing.assert_array_equal(angles, expected[:, header.index("angle")])
    if "t" in header:
        np.testing.assert_array_equal(times, expected[:, header.index("t")])
    else:
        np.testing.assert_array_equal(times, 0.5 * np.arange(len(body)))


def test_trace_reader_missing_file_and_folder(tmp_path):
    missing = tmp_path / "missing.csv"
    no_file = f"^{re.escape(str(missing))}: cannot read the file: No such file or directory$"
    with pytest.raises(InputFileError, match=no_file):
        read_angle_trace(missing)
    with pytest.raises(InputFileError, match=f"^{re.escape(str(tmp_path))}: cannot read the file: Is a directory$"):
        read_angle_trace(tmp_path)


# --- read_tum ---------------------------------------------------------------------------------

def _check_tum(path):
    try:
        rows = read_tum(path)
    except InputFileError as error:
        assert str(error).startswith(str(path)), str(error)
        return
    assert rows.ndim == 2 and rows.shape[1] == 8 and rows.shape[0] >= 1
    assert np.all(np.isfinite(rows))


tum_inputs = st.one_of(arbitrary_bytes, arbitrary_text, mutated(valid_tum_rows(), False))


@FUZZ
@given(data=tum_inputs)
def test_tum_reader_loads_or_raises_input_file_error(scratch, data):
    _check_tum(_write(scratch, data))


def test_tum_reader_missing_file_and_undecodable_bytes(tmp_path):
    missing = tmp_path / "missing.tum"
    no_file = f"^{re.escape(str(missing))}: cannot read the file: No such file or directory$"
    with pytest.raises(InputFileError, match=no_file):
        read_tum(missing)
    path = _write(tmp_path, b"0 0 0 0 0 0 0 1\n\xff\xfe 1 1\n")
    with pytest.raises(InputFileError, match=f"^{re.escape(str(path))}: cannot read the file: not UTF-8 text"):
        read_tum(path)


@FUZZ
@given(rows=st.lists(st.lists(finite, min_size=8, max_size=8), min_size=1, max_size=6),
       bom=st.booleans(), newline=st.sampled_from(["\n", "\r\n", "\r"]))
def test_valid_tum_round_trips_exactly(scratch, rows, bom, newline):
    """format_tum text, with a BOM or Windows/old-Mac line ends, reads back bit for bit."""
    expected = np.array(rows, dtype=float)
    text = format_tum(expected).replace("\n", newline)
    path = _write(scratch, (b"\xef\xbb\xbf" if bom else b"") + text.encode())
    np.testing.assert_array_equal(read_tum(path), expected)


def test_tum_error_names_the_line(tmp_path):
    path = _write(tmp_path, b"# t x y z qx qy qz qw\r\n0 0 0 0 0 0 0 1\r\n\r\n1 0 0 0 0 0 nan 1\r\n")
    with pytest.raises(InputFileError, match=f"^{re.escape(str(path))}:4: non-finite value$"):
        read_tum(path)
