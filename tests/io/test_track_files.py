"""Track files (SPEC 10): the reader's accepted forms, every rejected file, and the generator."""

from __future__ import annotations

import numpy as np
import pytest

from stslam.errors import InputFileError
from stslam.io.track_files import format_track, parse_track_text, read_track_file, write_track_file
from stslam.sim.track_generator import KINDS, TRUE_MODEL, generate_track, generate_tracks, minimum_jerk

ROWS = "\n".join(f"{0.1 * i:.1f} 2.0 3.0" for i in range(8))


def test_whitespace_commas_comments_and_metadata():
    text = ("# true_model: prismatic\n# onset_s: 0.5\n\n"
            + "\n".join(f"{0.1 * i:.1f}, 2.0,3.0   # row {i}" for i in range(8)) + "\n")
    track = parse_track_text(text, "a.txt")
    assert track.metadata == {"true_model": "prismatic", "onset_s": "0.5"}
    np.testing.assert_allclose(track.points_world[:, 0], 0.1 * np.arange(8))
    assert track.times_s is None and track.lines[0] == 4


def test_quaternion_columns_are_read_and_ignored():
    text = "\n".join(f"{i} 0 1 0 0 0 1" for i in range(8))
    track = parse_track_text(text, "q.txt")
    np.testing.assert_array_equal(track.points_world[3], [3.0, 0.0, 1.0])


def test_time_column():
    text = "\n".join(f"{0.5 * i} {i} 0 0 0 0 0 1" for i in range(8))
    track = parse_track_text(text, "t.txt", time_column=True)
    np.testing.assert_allclose(track.times_s, 0.5 * np.arange(8))
    np.testing.assert_allclose(track.points_world[:, 0], np.arange(8))


@pytest.mark.parametrize("text, kwargs, message", [
    ("", {}, r"^e\.txt: no observations"),
    ("# only a comment\n\n", {}, r"^e\.txt: no observations"),
    ("1 2 3\n1 2\n", {}, r"^e\.txt:2: ragged rows: expected 3 numbers"),
    ("1 2 3 4 5\n", {}, r"^e\.txt:1: expected 3 or 7 numbers per line"),
    ("1 2 3\n1 nan 3\n", {}, r"^e\.txt:2: values must be finite"),
    ("1 2 3\n1 inf 3\n", {}, r"^e\.txt:2: values must be finite"),
    ("1 2 3\n1 two 3\n", {}, r"^e\.txt:2: not a number: 'two'"),
    ("\n".join(ROWS.splitlines()[:3]), {}, r"^e\.txt: 3 observations, fewer than N_min = 7"),
    ("\n".join(f"{t} 1 2 3" for t in [0, 1, 2, 2, 3, 4, 5, 6]), {"time_column": True},
     r"^e\.txt:4: time must increase strictly: 2 s after 2 s"),
    ("1 2 3\n", {"time_column": True}, r"^e\.txt:1: expected 4 or 8 numbers per line"),
])
def test_bad_files_name_file_and_line(text, kwargs, message):
    with pytest.raises(InputFileError, match=message):
        parse_track_text(text, "e.txt", **kwargs)


def test_unreadable_files(tmp_path):
    with pytest.raises(InputFileError, match=r"missing\.txt: cannot be read"):
        read_track_file(tmp_path / "missing.txt")
    binary = tmp_path / "b.txt"
    binary.write_bytes(b"\xff\xfe\x00\x81")
    with pytest.raises(InputFileError, match=r"b\.txt: not a text file"):
        read_track_file(binary)


def test_format_and_read_round_trip(tmp_path):
    track = generate_track(np.random.default_rng(0), "door")
    path = write_track_file(tmp_path / "sub" / "door.txt",
                            format_track(track.points_world, track.times_s, track.metadata()))
    back = read_track_file(path, time_column=True)
    # Six decimals in the file: round-trip within 5e-7 m and s.
    np.testing.assert_allclose(back.points_world, track.points_world, atol=5e-7)
    np.testing.assert_allclose(back.times_s, track.times_s, atol=5e-7)
    assert back.metadata["true_model"] == "revolute"


def test_minimum_jerk_ends_at_rest():
    u = np.linspace(0, 1, 11)
    s = minimum_jerk(u)
    assert s[0] == 0.0 and s[-1] == 1.0 and np.all(np.diff(s) > 0)
    np.testing.assert_allclose(s[5], 0.5)  # symmetric profile


@pytest.mark.parametrize("kind", KINDS)
def test_generated_tracks_follow_their_joint(kind):
    track = generate_track(np.random.default_rng(7), kind)
    assert track.true_model == TRUE_MODEL[kind]
    before = track.times_s < track.onset_s
    # At rest before the onset: spread within 5σ of the noise.
    spread = np.abs(track.points_world[before] - track.points_world[before].mean(axis=0)).max()
    assert spread < 5 * track.noise_sigma_m
    # Noise-free distance to the joint's structure is zero, so the noisy RMS
    # distance is about σ·√2 (two normal directions) or σ (one, drawer: the
    # along-axis noise is free): allow 2σ.
    d = track.points_world - track.axis_point
    if kind == "drawer":
        off = d - np.outer(d @ track.axis_direction, track.axis_direction)
    else:
        along = d @ track.axis_direction
        radial = np.linalg.norm(d - np.outer(along, track.axis_direction), axis=1) - track.radius_m
        off = np.column_stack([radial, along - along.mean()])
    assert np.sqrt(np.mean(np.sum(off ** 2, axis=1))) < 2 * np.sqrt(2) * track.noise_sigma_m
    if kind == "dishwasher":  # horizontal hinge: axis ⟂ vertical, which is z or y of the capture frame
        assert min(abs(track.axis_direction[2]), abs(track.axis_direction[1])) < 1e-12


def test_generation_is_deterministic_and_cycles_kinds():
    a = generate_tracks(5, seed=3)
    b = generate_tracks(5, seed=3)
    assert [t.kind for t in a] == list(KINDS) + [KINDS[0]]
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x.points_world, y.points_world)
