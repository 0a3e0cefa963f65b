"""The staleness rule of experiments/reproduce.py on a temporary git repository.

The repository is a miniature of the project: a run script, a runner, two
experiment modules and shared modules, so the rule can be checked end to end:
which files a run depends on, which of them changed since a commit, and the
verdict for a results folder made at that commit.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from stslam.experiments.code_deps import experiment_dependencies, import_closure, imported_files
from stslam.experiments.reproduce import RunRecord, code_reason, judge
from stslam.io.git_tree import ChangeCache, changed_since, head_commit, resolve_commit

FILES = {
    "experiments/run.py": "def main():\n    from stslam.experiments.runner import execute\n",
    "experiments/make_things.py": "from stslam.sim import things\n",
    "stslam/__init__.py": "",
    "stslam/errors.py": "class StslamError(Exception):\n    pass\n",
    "stslam/experiments/__init__.py": "from stslam.errors import StslamError\n",
    "stslam/experiments/runner.py": "from stslam import experiments\nfrom stslam.io.results import write\n",
    "stslam/experiments/alpha.py": "from stslam.slam import core\nfrom .shared_helpers import helper\n",
    "stslam/experiments/beta.py": "import stslam.eval.metrics as metrics\n\n\ndef run():\n"
                                  "    from stslam.sim.things import make  # a lazy import counts\n",
    "stslam/experiments/shared_helpers.py": "def helper():\n    return 1\n",
    "stslam/io/__init__.py": "",
    "stslam/io/results.py": "import json\n",
    "stslam/slam/__init__.py": "",
    "stslam/slam/core.py": "from ..eval.metrics import ate\n",
    "stslam/eval/__init__.py": "",
    "stslam/eval/metrics.py": "import numpy as np\n\n\ndef ate():\n    return 0\n",
    "stslam/sim/__init__.py": "",
    "stslam/sim/things.py": "def make():\n    return 2\n",
    "conf/config.yaml": "seed: 0\n",
    "README.md": "demo\n",
}


def _git(root: Path, *args: str) -> str:
    return subprocess.run(["git", *args], cwd=root, check=True, capture_output=True, text=True).stdout.strip()


@pytest.fixture
def repo(tmp_path):
    """A committed miniature project; returns (root, short sha of its one commit)."""
    root = tmp_path / "repo"
    for relative, text in FILES.items():
        (root / relative).parent.mkdir(parents=True, exist_ok=True)
        (root / relative).write_text(text)
    _git(root, "init", "-q")
    _git(root, "add", "-A")
    _git(root, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", "start")
    return root, _git(root, "rev-parse", "--short", "HEAD")


def _commit(root: Path, message: str) -> str:
    _git(root, "add", "-A")
    _git(root, "-c", "user.name=t", "-c", "user.email=t@t", "commit", "-qm", message)
    return _git(root, "rev-parse", "--short", "HEAD")


COMMON = ["experiments/run.py", "stslam/__init__.py", "stslam/errors.py", "stslam/experiments/__init__.py",
          "stslam/experiments/runner.py", "stslam/io/__init__.py", "stslam/io/results.py"]


def test_dependencies_follow_imports_of_every_form(repo):
    root, _ = repo
    alpha = experiment_dependencies(root, "alpha")
    beta = experiment_dependencies(root, "beta")
    # `from pkg import module`, relative imports (one and two levels) and the packages' __init__.py
    assert alpha == sorted(COMMON + ["stslam/experiments/alpha.py", "stslam/experiments/shared_helpers.py",
                                     "stslam/slam/__init__.py", "stslam/slam/core.py",
                                     "stslam/eval/__init__.py", "stslam/eval/metrics.py"])
    # `import a.b as c` and an import inside a function
    assert beta == sorted(COMMON + ["stslam/experiments/beta.py", "stslam/eval/__init__.py",
                                    "stslam/eval/metrics.py", "stslam/sim/__init__.py", "stslam/sim/things.py"])
    # configuration and documentation are never code dependencies; numpy and json are not in the package
    assert not any(f.startswith("conf/") or f == "README.md" for f in alpha + beta)
    with_data = experiment_dependencies(root, "alpha", ("experiments/make_things.py",))
    assert {"experiments/make_things.py", "stslam/sim/things.py"} <= set(with_data)


def test_closure_of_a_package_init_and_unknown_experiment(repo):
    root, _ = repo
    assert imported_files(root, "stslam/experiments/__init__.py") == {"stslam/__init__.py", "stslam/errors.py"}
    assert import_closure(root, ["stslam/sim/things.py"]) == ["stslam/sim/things.py"]
    with pytest.raises(FileNotFoundError, match="stslam/experiments/gamma.py"):
        experiment_dependencies(root, "gamma")


def test_nothing_changed_right_after_the_commit(repo):
    root, sha = repo
    deps = experiment_dependencies(root, "alpha")
    assert changed_since(root, resolve_commit(root, sha), deps) == []
    assert head_commit(root).startswith(sha)


def test_an_experiment_module_edit_makes_only_its_runs_stale(repo):
    root, sha = repo
    (root / "stslam/experiments/beta.py").write_text(FILES["stslam/experiments/beta.py"] + "# edited\n")
    cache = ChangeCache(root)
    assert cache.changed(sha, experiment_dependencies(root, "alpha")) == []
    assert cache.changed(sha, experiment_dependencies(root, "beta")) == ["stslam/experiments/beta.py"]


def test_a_shared_module_edit_makes_every_importer_stale_even_once_committed(repo):
    root, sha = repo
    (root / "stslam/eval/metrics.py").write_text("def ate():\n    return 1\n")
    new_sha = _commit(root, "metrics")
    for exp in ("alpha", "beta"):
        deps = experiment_dependencies(root, exp)
        assert ChangeCache(root).changed(sha, deps) == ["stslam/eval/metrics.py"]
        assert ChangeCache(root).changed(new_sha, deps) == []  # a run made at the new commit is current


def test_edits_outside_the_dependencies_change_nothing(repo):
    root, sha = repo
    (root / "README.md").write_text("more\n")
    (root / "conf/config.yaml").write_text("seed: 1\n")  # judged by the resolved config, not here
    (root / "stslam/sim/things.py").write_text("def make():\n    return 3\n")  # beta's, not alpha's
    _commit(root, "other files")
    assert ChangeCache(root).changed(sha, experiment_dependencies(root, "alpha")) == []


def test_a_new_untracked_module_counts_as_changed(repo):
    root, sha = repo
    (root / "stslam/slam/extra.py").write_text("X = 1\n")
    (root / "stslam/slam/core.py").write_text("from stslam.slam import extra\n")
    changed = ChangeCache(root).changed(sha, experiment_dependencies(root, "alpha"))
    assert changed == ["stslam/slam/core.py", "stslam/slam/extra.py"]


def test_verdicts_of_a_results_folder(repo, tmp_path):
    root, sha = repo
    cache = ChangeCache(root)
    deps = experiment_dependencies(root, "alpha")
    config = {"exp_name": "alpha", "n_seeds": 5}

    def record(name, **version):
        return RunRecord(tmp_path / name, config, {"git_sha": sha, "git_dirty": False, **version})

    def verdict(*records):
        return judge("alpha", config, list(records), lambda r: code_reason(r, deps, cache.changed))

    assert not verdict(record("clean")).todo
    dirty = verdict(record("dirty", git_dirty=True))
    assert dirty.todo and "uncommitted changes" in dirty.reason
    unknown = verdict(record("elsewhere", git_sha="0123abc"))
    assert unknown.todo and "git 0123abc is not a commit of this repository" in unknown.reason
    assert verdict(record("nogit", git_sha="nogit")).todo
    # a dirty newer run does not hide a clean older one
    older, newer = record("a-older"), record("b-newer", git_dirty=True)
    kept = verdict(older, newer)
    assert not kept.todo and kept.record is older
    (root / "stslam/slam/core.py").write_text("# edited\n")
    cache = ChangeCache(root)  # a cache answers for the files as they were when it first read them
    edited = verdict(record("clean"))
    assert edited.todo and edited.reason.startswith(
        f"stale: 1 file it depends on changed since git {sha}: stslam/slam/core.py")
