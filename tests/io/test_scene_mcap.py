"""scene.mcap (SPEC 15): A-SLAM's run recorded per frame, encoded with Foxglove schemas, read back."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import compose_config
from mcap.reader import make_reader
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

from stslam.experiments.runner import execute
from stslam.io.scene_mcap import MODEL_COLOURS, Scene, SceneFrame, scene_mcap_bytes
from stslam.robot.sensor import sensor_from_config
from stslam.sim.simulate import simulate
from stslam.sim.worlds import world_from_config
from stslam.slam.filters import filter_params, make_filter, run_filter
from stslam.slam.scene_record import SceneRecorder, landmark_frames


def _decode(path_or_bytes):
    import io

    handle = open(path_or_bytes, "rb") if not isinstance(path_or_bytes, bytes) else io.BytesIO(path_or_bytes)
    with handle:
        reader = make_reader(handle)
        summary = reader.get_summary()
        schemas = {c.topic: (summary.schemas[c.schema_id].name, c.message_encoding) for c in summary.channels.values()}
        colours, mu = {}, []
        for _, channel, message in reader.iter_messages(log_time_order=True):
            if channel.topic == "/landmarks":
                for entity in SceneUpdate.FromString(message.data).entities:
                    if entity.id.startswith("landmark/"):
                        c = entity.spheres[0].color
                        colours.setdefault(int(entity.id.split("/")[1]), []).append(
                            (message.log_time, (c.r, c.g, c.b, c.a)))
            elif channel.topic == "/mu":
                mu.append(json.loads(message.data))
    return schemas, colours, mu


@pytest.fixture(scope="module")
def a_slam_run():
    cfg = compose_config("dynamic_slam", ["world.n_frames=120"])
    world = world_from_config(cfg)
    run = simulate(world, sensor_from_config(cfg), np.random.default_rng(0))
    spec = make_filter("a_slam", filter_params(cfg, "a_slam"), world)
    recorder = SceneRecorder()
    track = run_filter(spec, run, observer=recorder)
    return world, run, spec, track, recorder


def test_recording_does_not_change_the_run(a_slam_run):
    world, run, spec, track, recorder = a_slam_run
    np.testing.assert_array_equal(run_filter(spec, run).poses_xytheta, track.poses_xytheta)
    np.testing.assert_array_equal(np.array(recorder.poses), track.poses_xytheta)


def test_landmark_colour_changes_when_its_model_is_decided(a_slam_run):
    world, _, _, track, recorder = a_slam_run
    frames = landmark_frames(recorder, track.landmarks)
    times = np.arange(world.n_frames) * world.dt
    scene = Scene(times_s=times, paths={"a_slam": track.poses_xytheta},
                  frames=[SceneFrame(t_s=float(times[k]), ids=f.ids, positions=f.positions, models=f.models,
                                     joints=f.joints, mu=f.mu) for k, f in enumerate(frames)])
    schemas, colours, mu = _decode(scene_mcap_bytes(scene))
    assert schemas["/landmarks"] == ("foxglove.SceneUpdate", "protobuf")
    assert schemas["/mu"][1] == "json" and len(mu) == world.n_frames
    # Landmarks decided once and never restarted: grey up to the decision frame, the model's colour from it on.
    once = {i: r for i, r in track.landmarks.items() if len(r.decisions) == 1 and r.restarts == 0}
    assert once
    for i, report in once.items():
        frame, _, model = report.decisions[0]
        decided_ns = int(round(times[frame] * 1e9))
        before = {c for t, c in colours[i] if t < decided_ns}
        after = {c for t, c in colours[i] if t >= decided_ns}
        assert before <= {MODEL_COLOURS["undecided"]}
        assert after == {MODEL_COLOURS[model]}
    # μ of a decided landmark is in the plot messages.
    i = next(iter(once))
    assert any(row["id"] == i and set(row) >= {"static", "prismatic", "revolute"} for m in mu for row in m["landmarks"])


def test_dynamic_slam_run_writes_scene_mcap(tmp_path):
    folder = execute(compose_config("dynamic_slam", ["n_seeds=1", "world.n_frames=80"], out_dir=tmp_path))
    schemas, colours, _ = _decode(folder / "scene.mcap")
    assert schemas["/landmarks"][0] == "foxglove.SceneUpdate"
    assert schemas["/tf"][0] == "foxglove.FrameTransform"
    assert schemas["/trajectory/groundtruth"][0] == "foxglove.PosesInFrame"
    assert schemas["/pose/a_slam"][0] == "foxglove.PoseInFrame"
    grey = MODEL_COLOURS["undecided"]
    assert any(seq[0][1] == grey and seq[-1][1] != grey for seq in colours.values())


def test_scene_seeds_choose_the_files(tmp_path):
    folder = execute(compose_config("dynamic_slam", ["n_seeds=2", "world.n_frames=30", "scene.seeds=[0,1]",
                                                     "methods=[ekf_slam]"], out_dir=tmp_path))
    assert sorted(p.name for p in folder.glob("scene*.mcap")) == ["scene_seed0.mcap", "scene_seed1.mcap"]
    folder = execute(compose_config("dynamic_slam", ["n_seeds=1", "world.n_frames=30", "scene.seeds=[]",
                                                     "methods=[ekf_slam]"], out_dir=tmp_path / "none"))
    assert not list(folder.glob("scene*.mcap"))


def test_a_frame_reads_back_and_draws(a_slam_run, tmp_path):
    from stslam.io.scene_read import read_scene_frame
    from stslam.render.scene import scene_figure

    world, _, _, track, recorder = a_slam_run
    frames = landmark_frames(recorder, track.landmarks)
    times = np.arange(world.n_frames) * world.dt
    scene = Scene(times_s=times, paths={"groundtruth": world.poses_xytheta, "a_slam": track.poses_xytheta},
                  frames=[SceneFrame(t_s=float(times[k]), ids=f.ids, positions=f.positions, models=f.models,
                                     joints=f.joints, mu=f.mu) for k, f in enumerate(frames)])
    path = tmp_path / "scene.mcap"
    path.write_bytes(scene_mcap_bytes(scene))
    k = world.n_frames - 1
    snapshot = read_scene_frame(path, k)
    np.testing.assert_allclose(snapshot.positions, frames[k].positions)
    assert snapshot.models == list(frames[k].models) and len(snapshot.joints) == len(frames[k].joints)
    np.testing.assert_allclose(snapshot.paths["a_slam"], track.poses_xytheta[:, :2])
    scene_figure(snapshot).savefig(tmp_path / "view.png")
    from stslam.errors import InputFileError
    with pytest.raises(InputFileError, match=r"frame 999: the scene has frames 0 … 119"):
        read_scene_frame(path, 999)


@pytest.mark.parametrize("args,message", [([], "error: usage:"), (["nope.mcap", "x.png"], "error: nope.mcap: ")])
def test_scene_view_prints_one_error_line(tmp_path, args, message):
    import subprocess
    import sys

    from conftest import REPO

    done = subprocess.run([sys.executable, str(REPO / "experiments" / "scene_view.py"), *args], cwd=tmp_path,
                          capture_output=True, text=True, env={"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin",
                                                               "MPLBACKEND": "Agg"})
    assert done.returncode == 2 and done.stderr.startswith(message) and len(done.stderr.strip().splitlines()) == 1
