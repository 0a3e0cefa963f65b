"""classify_tracks on realistic camera-marker furniture tracks, with the batch baseline, and bad files of every kind."""

from __future__ import annotations

import pandas as pd

from stslam.experiments.runner import execute
from stslam.io.track_files import format_track, write_track_file
from stslam.sim.marker_camera import MarkerCamera
from stslam.sim.track_generator import generate_tracks


def test_realistic_tracks_end_decided_with_both_selectors_and_the_decision_columns(compose_exp, tmp_path):
    data = tmp_path / "tracks"
    for i, track in enumerate(generate_tracks(24, 9000, camera=MarkerCamera())):
        write_track_file(data / f"t{i:02d}_{track.kind}.txt",
                         format_track(track.points_world, None, track.metadata(), track.orientations_xyzw))
    folder = execute(compose_exp("classify_tracks", f"tracks.glob={data}/*.txt", "max_figures=0"))
    metrics = pd.read_csv(folder / "metrics.csv")
    assert len(metrics) == 24
    # Reference: 300 realistic tracks (seeds 0–299) 98.3–98.7% right online; allow 2 of 24 wrong.
    assert metrics["correct"].sum() >= 22
    assert (metrics["model"] != "undecided").all()  # every track moved more than min_motion_m
    assert set(metrics["decided_by"]) <= {"online", "revised", "final"}
    assert {"first_model", "first_step", "revisions", "final_argmax", "batch_model", "batch_correct",
            "batch_bic_revolute"} <= set(metrics.columns)
    # The decision reads p_<model>: the decided model is the arg-max of p wherever the final arg-max decided it.
    p = metrics[["p_static", "p_prismatic", "p_revolute"]].to_numpy()
    assert abs(p.sum(axis=1) - 1).max() < 1e-9  # probabilities over the three models
    final = metrics["decided_by"] == "final"
    assert (metrics.loc[final, "model"] == metrics.loc[final, "final_argmax"]).all()
    revised = metrics[metrics["revisions"] > 0]
    assert (revised["first_model"] != revised["model"]).all() or revised.empty
    per_class = pd.read_csv(folder / "per_class.csv")
    assert set(per_class["kind"]) == {"door", "cabinet_door", "dishwasher", "drawer", "sliding_door", "flap"}
    assert (per_class["n"] == 4).all()


def test_one_bad_file_never_stops_the_batch(compose_exp, tmp_path, capsys):
    data = tmp_path / "mixed"
    for i, track in enumerate(generate_tracks(2, 9100, camera=MarkerCamera())):
        write_track_file(data / f"good_{i}.txt", format_track(track.points_world, None, track.metadata()))
    bad = {"huge.txt": "1e300 1e300 1e300\n" * 20, "nan.txt": "1 2 3\n" * 8 + "nan 1 2\n",
           "ragged.txt": "1 2 3\n1 2 3 4\n" * 5, "columns.txt": "1 2 3 4 5\n" * 10, "empty.txt": "",
           "words.txt": "hello world\n"}
    for name, text in bad.items():
        write_track_file(data / name, text)
    (data / "binary.txt").write_bytes(bytes(range(256)) * 4)
    folder = execute(compose_exp("classify_tracks", f"tracks.glob={data}/*.txt", "max_figures=0"))
    metrics = pd.read_csv(folder / "metrics.csv")
    errors = pd.read_csv(folder / "errors.csv")
    assert len(metrics) == 2 and len(errors) == len(bad) + 1
    out = capsys.readouterr().out
    assert sum(line.startswith("error: ") for line in out.splitlines()) == len(bad) + 1
    assert "beyond" in errors.set_index("file").loc[str(data / "huge.txt"), "problem"]
