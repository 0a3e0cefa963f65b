"""A user's recording end to end (SPEC 15): ROS 2 and ROS 1 bags → convert.py → fridge, with and without truth."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from bag_writer import write_bag
from mcap_rename import RENAMED, RENAMED_KEYS, renamed_copy
from conftest import compose_config
from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from stslam.config.convert import convert_from_config
from stslam.experiments.runner import execute
from stslam.io.bag_convert import convert_bag
from stslam.io.mcap_write import write_fridge_mcap
from stslam.io.scene_mcap import MODEL_COLOURS
from stslam.rgbd.sequence import FridgeSequence, SequenceConfig

# The short sequence of test_fridge.py: 90 frames at 160 × 120, the door opens and closes within it.
SHORT = SequenceConfig(n_frames=90, width=160, height=120)
SEED = 7
OVERRIDES = [f"seed={SEED}", "landmarks.min_track_frames=20", "filters.a_slam.common_axis.min_tracks=5"]
METHODS = ("odometry", "ekf_slam", "dyn_slam", "ekf_slam_gated", "a_slam")


def _run(mcap, out, *overrides):
    return execute(compose_config("fridge", [f"mcap={mcap}", *OVERRIDES, *overrides], out_dir=out))


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """The original MCAP, the bags made from it, their conversions and one fridge run of each."""
    root = tmp_path_factory.mktemp("rosbag")
    original = root / "short.mcap"
    write_fridge_mcap(original, FridgeSequence(SHORT, SEED))
    bags = {"ros2": write_bag(original, root / "ros2_bag", ros=2),
            "ros1": write_bag(original, root / "rec.bag", ros=1),
            "no_truth": write_bag(original, root / "no_truth_bag", ros=2, storage="mcap", ground_truth=False)}
    runs = {"original": _run(original, root / "r_original"),
            "renamed": _run(renamed_copy(original, root / "renamed.mcap"), root / "r_renamed",
                            *(f"mcap_topics.{RENAMED_KEYS[old]}={new}" for old, new in RENAMED.items()))}
    for name, bag in bags.items():
        out = root / f"{name}.mcap"
        convert_bag(convert_from_config(compose_convert(bag, out)))
        runs[name] = _run(out, root / f"r_{name}")
    return runs


def compose_convert(bag, out, *overrides):
    from hydra import compose, initialize_config_dir
    from omegaconf import OmegaConf

    from conftest import CONF

    with initialize_config_dir(config_dir=str(CONF), version_base="1.3"):
        cfg = compose("convert", overrides=[f"bag={bag}", f"out={out}", "progress=false", *overrides])
    return OmegaConf.to_container(cfg, resolve=True)


def _metrics(folder) -> pd.DataFrame:
    return pd.read_csv(folder / "metrics.csv").set_index("method")


@pytest.mark.parametrize("name", ["ros2", "ros1"])
def test_converted_bag_gives_a_slam_ate_within_10_percent(recordings, name):
    original = _metrics(recordings["original"]).loc["a_slam", "ate_m"]
    converted = _metrics(recordings[name]).loc["a_slam", "ate_m"]
    assert np.isfinite(original) and abs(converted - original) <= 0.1 * original
    # Raw colour, 32FC1 depth and poses survive the round trip exactly: the same numbers.
    pd.testing.assert_series_equal(_metrics(recordings[name])["ate_m"], _metrics(recordings["original"])["ate_m"])


def test_a_recording_with_other_topic_names_runs_with_mcap_topics(recordings):
    # The same messages under other names: the same numbers to the last digit, and the scene's images.
    pd.testing.assert_frame_equal(_metrics(recordings["renamed"]), _metrics(recordings["original"]))
    schemas, _, n_annotations = _scene(recordings["renamed"])
    assert n_annotations > 0 and schemas["/camera/image"] == "foxglove.CompressedImage"


def test_converted_bag_without_door_truth_says_which_metrics_are_missing(recordings):
    folder = recordings["ros2"]
    row = _metrics(folder).loc["a_slam"]
    assert np.isnan(row["axis_angle_deg"]) and np.isnan(row["axis_dist_m"]) and row["n_revolute"] >= 1
    missing = pd.read_csv(folder / "not_computed.csv")
    assert set(missing["metric"]) == {"axis_angle_deg", "axis_dist_m", "axis_angle_deg_true_poses",
                                      "axis_dist_m_true_poses"}
    assert (missing["reason"] == "the recording has no door ground truth").all()
    structures = pd.read_csv(folder / "structures.csv")
    assert "axis" in set(structures["kind"]) and (structures["model"] == "revolute").any()


def test_bag_without_ground_truth_runs_and_writes_every_trajectory(recordings):
    folder = recordings["no_truth"]
    metrics = _metrics(folder)
    assert set(METHODS) <= set(metrics.index)
    assert metrics["ate_m"].isna().all() and metrics["rpe_m"].isna().all()
    missing = pd.read_csv(folder / "not_computed.csv")
    assert {"ate_m", "rpe_m", "nees"} <= set(missing["metric"])
    names = sorted(p.name for p in (folder / "trajectories").iterdir())
    assert names == sorted(f"{m}_seed{SEED}.tum" for m in METHODS)  # no ground truth file
    for name in names:
        rows = np.loadtxt(folder / "trajectories" / name)
        assert rows.shape == (SHORT.n_frames, 8) and np.all(np.isfinite(rows))
    # A-SLAM still finds the door: its structures without any truth to score them.
    structures = pd.read_csv(folder / "structures.csv")
    assert (structures["model"] == "revolute").any()


def _scene(folder):
    with open(folder / "scene.mcap", "rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        summary = reader.get_summary()
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        colours: dict = {}
        n_annotations = 0
        for _, channel, _, decoded in reader.iter_decoded_messages(topics=["/landmarks", "/camera/corners"]):
            if channel.topic == "/camera/corners":
                n_annotations += sum(len(p.points) for p in decoded.points)
                continue
            for entity in decoded.entities:
                if entity.id.startswith("landmark/") and entity.spheres:
                    c = entity.spheres[0].color
                    colours.setdefault(entity.id, []).append((c.r, c.g, c.b, c.a))
    return schemas, colours, n_annotations


def test_fridge_scene_holds_landmarks_poses_and_annotated_images(recordings):
    schemas, colours, n_annotations = _scene(recordings["original"])
    assert schemas["/landmarks"] == "foxglove.SceneUpdate"
    assert schemas["/tf"] == "foxglove.FrameTransform" and schemas["/trajectory/a_slam"] == "foxglove.PosesInFrame"
    assert schemas["/camera/corners"] == "foxglove.ImageAnnotations" and n_annotations > 0
    grey, blue = (pytest.approx(MODEL_COLOURS[m]) for m in ("undecided", "revolute"))
    # A door landmark starts grey (undecided) and turns blue once held revolute.
    turned = [seq for seq in colours.values() if seq[0] == grey and seq[-1] == blue]
    assert turned
    assert not (recordings["original"] / "not_computed.csv").exists()
