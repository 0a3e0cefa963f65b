"""``experiments/bench.py --against COMMIT`` (stslam.experiments.baseline): the other commit's own benchmark run
in a scratch git worktree with the same options, its folder found, the worktree removed, and clear errors."""

from __future__ import annotations

import shutil
import subprocess

import pytest

from stslam.errors import ConfigError
from stslam.experiments.baseline import git, run_baseline, shared_arguments

from test_bench_rows import _bench

pytestmark = pytest.mark.skipif(shutil.which("git") is None, reason="needs git")

# A stand-in for an old commit's experiments/bench.py: it writes one run folder holding its arguments and the
# stslam it imported (its own, first on the path), as the real one writes results/bench/<stamp>-<sha>/.
FAKE_BENCH = '''import sys, pathlib, stslam
args = sys.argv[1:]
out = pathlib.Path(args[args.index("--out-dir") + 1]) / "bench" / "20260101-000000-old"
out.mkdir(parents=True)
(out / "args.txt").write_text(" ".join(args))
(out / "stslam.txt").write_text(stslam.__file__)
'''


def _repo(tmp_path, files: dict) -> tuple:
    repo = tmp_path / "repo"
    repo.mkdir()
    for name, text in files.items():
        (repo / name).parent.mkdir(parents=True, exist_ok=True)
        (repo / name).write_text(text)
    for command in (["init", "-q"], ["add", "-A"],
                    ["-c", "user.name=t", "-c", "user.email=t@t", "commit", "-q", "-m", "old"]):
        subprocess.run(["git", "-C", str(repo), *command], check=True)
    return repo, git(repo, "rev-parse", "HEAD")


def test_the_baseline_runs_its_own_bench_with_the_shared_options_and_its_worktree_goes(tmp_path):
    repo, sha = _repo(tmp_path, {"experiments/bench.py": FAKE_BENCH, "stslam/__init__.py": ""})
    folder = run_baseline(sha[:7], ["--seeds", "3", "--skip-isam2"], repo, tmp_path / "results")
    assert folder == tmp_path / "results" / "bench" / "20260101-000000-old"
    assert (folder / "args.txt").read_text() == f"--seeds 3 --skip-isam2 --out-dir {tmp_path / 'results'}"
    assert "stslam-baseline-" in (folder / "stslam.txt").read_text()  # the old commit's package, not ours
    assert git(repo, "worktree", "list").count("\n") == 0  # only the repository's own tree is left


def test_an_unknown_commit_and_a_commit_without_a_benchmark_are_named(tmp_path):
    repo, sha = _repo(tmp_path, {"README.md": "old\n"})
    with pytest.raises(ConfigError, match="--against no-such-commit: not a commit of the git repository"):
        run_baseline("no-such-commit", [], repo, tmp_path / "results")
    with pytest.raises(ConfigError, match=f"--against {sha[:7]}: that commit has no experiments/bench.py"):
        run_baseline(sha[:7], [], repo, tmp_path / "results")
    assert git(repo, "worktree", "list").count("\n") == 0


def test_a_failing_baseline_run_is_reported_with_its_exit_code(tmp_path):
    repo, sha = _repo(tmp_path, {"experiments/bench.py": "import sys; sys.exit(3)\n"})
    with pytest.raises(ConfigError, match="ended with exit code 3"):
        run_baseline(sha, [], repo, tmp_path / "results")


def test_shared_arguments_give_a_baseline_the_same_options_but_not_this_runs_own():
    bench = _bench()
    args = bench._parser().parse_args(["--seeds", "3", "--repeats", "2", "--worlds", "kitchen", "--skip-isam2",
                                       "--against", "3c73d16", "--out-dir", "elsewhere"])
    shared = shared_arguments(args)
    again = bench._parser().parse_args(shared)
    for option in ("seeds", "repeats", "worlds", "sizes", "frontend_frames", "skip_isam2", "skip_frontend",
                   "selection_only"):
        assert getattr(again, option) == getattr(args, option), option
    assert "--against" not in shared and "--out-dir" not in shared and "--compare" not in shared


def test_selection_only_cannot_be_compared(capsys):
    with pytest.raises(SystemExit):
        _bench().main(["--selection-only", "--against", "3c73d16"])
    assert "--selection-only writes no run to compare" in capsys.readouterr().err
