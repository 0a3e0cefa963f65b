"""Which run ``resume=true`` continues, and when it refuses (SPEC 12, 18)."""

from __future__ import annotations

import hashlib

import pytest

from stslam.errors import ConfigError
from stslam.experiments import resume
from stslam.experiments.resume import abandon, read_jobs, resume_command, seed_runner
from stslam.experiments.seeds import SeedRunner


def _config(out_dir, **changes) -> dict:
    config = {"exp_name": "demo", "seed": 0, "n_seeds": 3, "out_dir": str(out_dir), "progress": False,
              "jobs": 1, "resume": False, "world": {"name": "kitchen", "n_frames": 330}}
    for key, value in changes.items():
        config[key] = value
    return config


def _digest(folder) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
            for p in sorted(folder.rglob("*"))}


def _interrupted(tmp_path, **changes) -> SeedRunner:
    """A run that finished 2 of its 3 seeds and was then stopped."""
    seeds = seed_runner(_config(tmp_path, **changes), "demo", tmp_path)
    seeds.checkpoints = seeds.make_checkpoints()
    for k in range(2):
        seeds.checkpoints.save("demo", k, [k * 10])
    seeds.checkpoints.close()
    return seeds


def test_a_new_run_makes_its_folder_only_when_its_seeds_start(tmp_path, capsys):
    seeds = seed_runner(_config(tmp_path), "demo", tmp_path)
    assert not (tmp_path / "demo").exists()  # a run refused while checking its config leaves nothing
    assert seeds.map(lambda k: k, 3, "demo", enabled=False) == [0, 1, 2]
    folder = seeds.checkpoints.folder
    assert folder.parent == tmp_path / "demo" and folder.name.startswith(".incomplete-")
    assert capsys.readouterr().out == ""


def test_resume_continues_the_same_config_whatever_jobs_and_progress(tmp_path, capsys):
    first = _interrupted(tmp_path)
    again = seed_runner(_config(tmp_path, resume=True, jobs=2, progress=True), "demo", tmp_path)
    assert again.checkpoints.folder == first.checkpoints.folder and again.jobs == 2
    assert f"resume: continuing {first.checkpoints.folder} (2 finished unit(s) of work kept)" in capsys.readouterr().out
    calls = []
    again.jobs = 1  # here, so that the calls can be counted
    assert again.map(lambda k: calls.append(k) or k * 10, 3, "demo", enabled=False) == [0, 10, 20]
    assert calls == [2] and again.resumed_seeds == 2


def test_the_newest_incomplete_run_of_the_config_is_continued(tmp_path):
    _interrupted(tmp_path)
    newer = _interrupted(tmp_path)  # same second, same process: a "-1" name
    _interrupted(tmp_path, seed=5)  # newest of all, but another config
    again = seed_runner(_config(tmp_path, resume=True), "demo", tmp_path)
    assert again.checkpoints.folder == newer.checkpoints.folder


def test_a_different_config_is_refused_naming_the_keys_and_nothing_changes(tmp_path):
    _interrupted(tmp_path)
    before = _digest(tmp_path)
    with pytest.raises(ConfigError, match=r"^resume: no incomplete demo run under .* has this config; the newest, "
                                          r"\.incomplete-.*, differs in world\.n_frames: 330 → 110; "
                                          r"world\.name: 'kitchen' → 'square_centred'\. Nothing was changed"):
        seed_runner(_config(tmp_path, resume=True, world={"name": "square_centred", "n_frames": 110}), "demo",
                    tmp_path)
    assert _digest(tmp_path) == before


def test_another_commit_is_another_config(tmp_path, monkeypatch):
    _interrupted(tmp_path)
    monkeypatch.setattr(resume, "git_state", lambda: ("0123abc", False))
    with pytest.raises(ConfigError, match=r"differs in git_sha: '[0-9a-f]+' → '0123abc'"):
        seed_runner(_config(tmp_path, resume=True), "demo", tmp_path)


def test_a_sweep_job_with_only_other_configs_starts_afresh(tmp_path, capsys):
    _interrupted(tmp_path, seed=50)
    seeds = seed_runner(_config(tmp_path, resume=True), "demo", tmp_path, in_sweep=True)
    assert seeds.checkpoints is None and seeds.make_checkpoints is not None
    assert "(1 of other configs left as they are); running from scratch" in capsys.readouterr().out


def test_nothing_to_resume_runs_from_scratch_and_says_so(tmp_path, capsys):
    seeds = seed_runner(_config(tmp_path, resume=True), "demo", tmp_path)
    assert seeds.checkpoints is None
    assert capsys.readouterr().out == (f"resume: no incomplete demo run of this config under {tmp_path / 'demo'}; "
                                       "running from scratch\n")


def test_a_run_in_use_by_another_process_is_refused(tmp_path):
    first = seed_runner(_config(tmp_path), "demo", tmp_path)
    first.map(lambda k: k, 1, "demo", enabled=False)  # holds its lock, as a live run does
    with pytest.raises(ConfigError, match="is being run by another process"):
        seed_runner(_config(tmp_path, resume=True), "demo", tmp_path)


def test_abandon_keeps_finished_seeds_and_says_how_to_continue(tmp_path, capsys):
    seeds = _interrupted(tmp_path)
    seeds.done_seeds = 2
    abandon(seeds, KeyboardInterrupt())
    assert seeds.checkpoints.folder.is_dir()
    err = capsys.readouterr().err
    assert f"the 2 finished seed(s) are kept in {seeds.checkpoints.folder}; continue with: python" in err


def test_abandon_leaves_no_folder_when_no_seed_finished(tmp_path):
    seeds = seed_runner(_config(tmp_path), "demo", tmp_path)
    seeds.checkpoints = seeds.make_checkpoints()
    abandon(seeds, RuntimeError("bug"))
    assert list((tmp_path / "demo").iterdir()) == []


@pytest.mark.parametrize("value", [0, -2, 1.5, True, "4"])
def test_bad_jobs_is_named(tmp_path, value):
    with pytest.raises(ConfigError, match=r"^jobs: expected an integer ≥ 1, or -1 for every core, got "):
        read_jobs(_config(tmp_path, jobs=value))


def test_every_core_and_the_resume_command():
    assert read_jobs({"jobs": -1}) >= 1
    assert resume_command(["experiments/run.py", "+exp=fridge", "resume=false", "n_seeds=10"], "fridge") == \
        "python experiments/run.py +exp=fridge n_seeds=10 resume=true"
