"""User trace files (SPEC 8.2): the two accepted layouts and every rejected file."""

from __future__ import annotations

import re

import numpy as np
import pytest

from stslam.errors import InputFileError
from stslam.io.trace_csv import read_angle_trace


def _write(tmp_path, text, name="trace.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_time_and_angle_columns(tmp_path):
    path = _write(tmp_path, "t,angle\n0.0,0.6\n0.5,0.7\n1.25,0.9\n\n")  # blank lines are skipped
    times, angles = read_angle_trace(path, min_rows=3)
    np.testing.assert_array_equal(times, [0.0, 0.5, 1.25])
    np.testing.assert_array_equal(angles, [0.6, 0.7, 0.9])


def test_columns_in_any_order_with_spaces_and_a_byte_order_mark(tmp_path):
    path = tmp_path / "bom.csv"
    path.write_bytes("\ufeffangle , T\n0.6, 10\n0.8, 11\n".encode("utf-8"))
    times, angles = read_angle_trace(path)
    np.testing.assert_array_equal(times, [10.0, 11.0])
    np.testing.assert_array_equal(angles, [0.6, 0.8])


def test_angle_only_uses_dt(tmp_path):
    path = _write(tmp_path, "angle\n" + "\n".join(str(0.1 * i) for i in range(6)) + "\n")
    times, angles = read_angle_trace(path, dt=0.25, min_rows=6)
    np.testing.assert_array_equal(times, 0.25 * np.arange(6))
    np.testing.assert_allclose(angles, 0.1 * np.arange(6), rtol=1e-15)


def _error(path, line, problem):
    """Pattern of the one-line message 'path:line: problem'."""
    where = re.escape(f"{path}:{line}" if line is not None else str(path))
    return f"^{where}: {problem}"


@pytest.mark.parametrize("text, line, problem", [
    ("", None, "empty file: expected a header row"),
    ("\n\n", None, "empty file"),
    ("t,value\n0,1\n1,2\n", 1, "missing column 'angle' in header 't,value'"),
    ("t,angle,x\n0,1,2\n1,2,3\n", 1, "unexpected columns in header 't,angle,x'"),
    ("angle,angle\n0,1\n1,2\n", 1, "unexpected columns"),
    ("t,angle\n0,0.6\n1,0.7,3\n2,0.8\n", 3, "expected 2 cells as in the header, got 3"),
    ("t,angle\n0,0.6\n1\n2,0.8\n", 3, "expected 2 cells as in the header, got 1"),
    ("t,angle\n0,0.6\n1,open\n2,0.8\n", 3, r"column 'angle': expected a number, got 'open'"),
    ("t,angle\n0,0.6\n1,NaN\n2,0.8\n", 3, r"column 'angle': expected a finite number, got 'NaN'"),
    ("t,angle\n0,0.6\n1,\n2,0.8\n", 3, r"column 'angle': expected a number, got ''"),
    ("t,angle\n0,0.6\ninf,0.7\n2,0.8\n", 3, r"column 't': expected a finite number, got 'inf'"),
    ("t,angle\n0,0.6\n1,0.7\n1,0.8\n", 4, r"time 1.0 does not increase \(previous row: 1.0\)"),
    ("t,angle\n0,0.6\n2,0.7\n1,0.8\n", 4, r"time 1.0 does not increase \(previous row: 2.0\)"),
    ("t,angle\n0,0.6\n1,0.7\n", None, r"2 data rows: expected at least 3"),
])
def test_bad_files_name_the_file_and_line(tmp_path, text, line, problem):
    path = _write(tmp_path, text)
    with pytest.raises(InputFileError, match=_error(path, line, problem)) as caught:
        read_angle_trace(path, dt=1.0, min_rows=3)
    assert caught.value.line == line


def test_angle_only_without_dt(tmp_path):
    path = _write(tmp_path, "angle\n0.1\n0.2\n0.3\n")
    with pytest.raises(InputFileError, match=_error(path, None, r"no 't' column and no time step dt > 0 given")):
        read_angle_trace(path)


def test_missing_file(tmp_path):
    path = tmp_path / "nowhere.csv"
    with pytest.raises(InputFileError, match=_error(path, None, "cannot read the file")):
        read_angle_trace(path)


def test_binary_file(tmp_path):
    path = tmp_path / "image.csv"
    path.write_bytes(b"\x89PNG\r\n\x1a\n\xff\xfe\x00")
    with pytest.raises(InputFileError, match=_error(path, None, "cannot read the file")):
        read_angle_trace(path)
