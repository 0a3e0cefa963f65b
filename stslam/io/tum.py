"""TUM trajectory files: ``t x y z qx qy qz qw`` per line (SPEC 7).

Quaternions are in TUM order (x, y, z, w). A planar robot pose (x, y, θ) maps
to z = 0 and the yaw quaternion (0, 0, sin θ/2, cos θ/2).
"""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from stslam.errors import InputFileError


def tum_from_planar(times_s, poses_xytheta) -> np.ndarray:
    """TUM rows from planar poses.

    Parameters
    ----------
    times_s : array_like, shape (n,)
        Time stamps in seconds.
    poses_xytheta : array_like, shape (n, 3)
        Robot poses (x m, y m, θ rad) in the world frame.

    Returns
    -------
    numpy.ndarray, shape (n, 8)
        ``t x y 0 0 0 sin(θ/2) cos(θ/2)``.
    """
    t = np.asarray(times_s, dtype=float).reshape(-1)
    p = np.asarray(poses_xytheta, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] != t.size:
        raise ValueError(f"poses_xytheta must have shape ({t.size}, 3), got {p.shape}")
    half = 0.5 * p[:, 2]
    zeros = np.zeros_like(t)
    return np.column_stack([t, p[:, 0], p[:, 1], zeros, zeros, zeros, np.sin(half), np.cos(half)])


def format_tum(rows: np.ndarray) -> str:
    """Text of a TUM file; numbers written in full round-trip precision."""
    rows = np.asarray(rows, dtype=float)
    if rows.ndim != 2 or rows.shape[1] != 8:
        raise ValueError(f"TUM rows must have shape (n, 8), got {rows.shape}")
    buffer = io.StringIO()
    for row in rows:
        buffer.write(" ".join(repr(float(v)) for v in row) + "\n")
    return buffer.getvalue()


def write_tum(path, rows: np.ndarray) -> None:
    """Write TUM rows (shape (n, 8)) to ``path``."""
    Path(path).write_text(format_tum(rows))


def read_tum(path) -> np.ndarray:
    """Read a TUM file into an array of shape (n, 8); ``#`` lines are comments.

    Raises
    ------
    InputFileError
        Unreadable or non-UTF-8 file, a line without 8 finite numbers, or no poses.
    """
    try:
        lines = Path(path).read_text(encoding="utf-8-sig").split("\n")  # \r, \r\n read as \n; a BOM is dropped
    except OSError as error:
        raise InputFileError(path, f"cannot read the file: {error.strerror or error}") from None
    except UnicodeDecodeError as error:
        raise InputFileError(path, f"cannot read the file: not UTF-8 text (byte {error.start})") from None
    rows = []
    for number, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        fields = text.replace(",", " ").split()
        if len(fields) != 8:
            raise InputFileError(path, f"expected 8 numbers (t x y z qx qy qz qw), got {len(fields)}", number)
        try:
            values = [float(v) for v in fields]
        except ValueError:
            raise InputFileError(path, "expected numbers (t x y z qx qy qz qw)", number) from None
        if not np.all(np.isfinite(values)):
            raise InputFileError(path, "non-finite value", number)
        rows.append(values)
    if not rows:
        raise InputFileError(path, "no poses in file")
    return np.asarray(rows, dtype=float)
