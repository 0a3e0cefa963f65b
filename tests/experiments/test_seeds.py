"""The seed runner (SPEC 12, 18): order, checkpoints, workers, and how a worker's end is reported."""

from __future__ import annotations

import os
import signal

import numpy as np
import pytest

from stslam.errors import ConfigError, InputFileError, StslamError
from stslam.experiments.seeds import SeedRunner, SeedWorkerDied
from stslam.io.checkpoints import RunCheckpoints, run_meta

pytestmark = pytest.mark.skipif(not hasattr(os, "fork"), reason="workers are forked")


def _store(tmp_path, name="run") -> RunCheckpoints:
    return RunCheckpoints.create(tmp_path / f".incomplete-{name}", run_meta("demo", {"seed": 0}, "abc"))


def _draws(k: int) -> dict:
    """A seed's result as a driver's: its own generator's numbers, an array and a row."""
    rng = np.random.default_rng(100 + k)
    return {"k": k, "pid": os.getpid(), "draws": rng.normal(size=5), "row": {"seed": 100 + k, "x": float(rng.random())}}


@pytest.mark.parametrize("jobs, block", [(1, 1), (3, 1), (2, 3)])
def test_results_in_seed_order_and_identical_whatever_jobs(tmp_path, jobs, block):
    expected = [_draws(k) for k in range(7)]
    runner = SeedRunner(jobs=jobs, checkpoints=_store(tmp_path))
    got = runner.map(_draws, 7, "demo", enabled=False, block=block)
    assert [g["k"] for g in got] == list(range(7))
    for g, e in zip(got, expected):
        np.testing.assert_array_equal(g["draws"], e["draws"])  # bit for bit: same generator, same seed
        assert g["row"] == e["row"]
    pids = {g["pid"] for g in got}
    # jobs=1 computes here; with workers every unit has a fresh process (one pid per unit)
    assert pids == ({os.getpid()} if jobs == 1 else set(pids) - {os.getpid()})
    if jobs > 1:
        assert len(pids) == -(-7 // block)
        assert runner.workers_used == min(jobs, -(-7 // block)) and runner.peak_worker_kib > 0
    assert runner.done_seeds == 7 and runner.resumed_seeds == 0
    assert runner.checkpoints.n_units() == -(-7 // block)


def test_kept_units_are_read_back_not_computed(tmp_path):
    store = _store(tmp_path)
    SeedRunner(checkpoints=store).map(_draws, 3, "demo", enabled=False)
    store.close()
    calls = []

    def counted(k):
        calls.append(k)
        return _draws(k)

    again = SeedRunner(checkpoints=RunCheckpoints.open(tmp_path / ".incomplete-run"))
    (again.checkpoints.state / "demo-1.pkl").unlink()  # as if the run had been killed during seed 1
    got = again.map(counted, 3, "demo", enabled=False)
    assert calls == [1]
    assert again.resumed_seeds == 2 and again.done_seeds == 3
    np.testing.assert_array_equal(got[2]["draws"], _draws(2)["draws"])


def test_a_damaged_checkpoint_is_computed_again(tmp_path):
    store = _store(tmp_path)
    SeedRunner(checkpoints=store).map(_draws, 2, "demo", enabled=False)
    (store.state / "demo-0.pkl").write_bytes(b"\x80\x05 cut short")
    again = SeedRunner(checkpoints=store)
    got = again.map(_draws, 2, "demo", enabled=False)
    assert again.resumed_seeds == 1
    np.testing.assert_array_equal(got[0]["draws"], _draws(0)["draws"])


def test_without_a_store_seeds_run_here_and_nothing_is_kept(tmp_path):
    got = SeedRunner(jobs=4).map(_draws, 3, "demo", enabled=False)
    assert {g["pid"] for g in got} == {os.getpid()}
    assert list(tmp_path.iterdir()) == []


def test_a_killed_worker_stops_the_run_naming_its_seed_and_keeps_the_others(tmp_path):
    def work(k):
        if k == 2:
            os.kill(os.getpid(), signal.SIGKILL)  # as the out-of-memory killer would
        return _draws(k)

    runner = SeedRunner(jobs=2, checkpoints=_store(tmp_path), seed0=40, hint="python run.py resume=true")
    with pytest.raises(SeedWorkerDied) as caught:
        runner.map(work, 5, "demo", enabled=False)
    message = str(caught.value)
    assert message.startswith("seed 42: its worker process was killed by signal 9 (SIGKILL")
    assert "continue with: python run.py resume=true" in message and str(runner.checkpoints.folder) in message
    kept = sorted(p.name for p in runner.checkpoints.state.glob("*.pkl"))
    # Seeds 0 and 1 ran before or beside seed 2, and finished: kept. Seed 3 (started beside 2, or not
    # at all) is kept only if it ran; no seed after the failure is started.
    assert {"demo-0.pkl", "demo-1.pkl"} <= set(kept) and "demo-2.pkl" not in kept and "demo-4.pkl" not in kept
    assert f"the {len(kept)} finished seed(s) are kept" in message


@pytest.mark.parametrize("error, expected", [
    (ValueError("bug in seed 1"), ValueError),
    (ConfigError("door.n_samples: expected ≥ 3"), ConfigError),
    # InputFileError's __init__ takes (path, problem): it does not unpickle from its message alone
    (InputFileError("tracks.csv", "expected 4 columns", line=3), StslamError),
], ids=["bug", "user-error", "not-unpicklable"])
def test_an_exception_in_a_worker_is_raised_again_as_with_one_job(tmp_path, error, expected):
    def work(k):
        if k == 1:
            raise error
        return k

    with pytest.raises(expected) as caught:
        SeedRunner(jobs=2, checkpoints=_store(tmp_path), seed0=10).map(work, 3, "demo", enabled=False)
    assert str(caught.value) == str(error)
    if expected is not StslamError:
        assert "raised in the worker process of seed 11" in "".join(caught.value.__notes__)


def test_one_map_per_label(tmp_path):
    runner = SeedRunner(checkpoints=_store(tmp_path))
    runner.map(_draws, 1, "demo", enabled=False)
    with pytest.raises(ValueError, match="already mapped"):
        runner.map(_draws, 1, "demo", enabled=False)


def test_a_second_process_cannot_take_a_run_in_use(tmp_path):
    from stslam.io.checkpoints import RunLocked

    store = _store(tmp_path)
    with pytest.raises(RunLocked):
        RunCheckpoints.open(store.folder)
    store.close()
    RunCheckpoints.open(store.folder).close()
