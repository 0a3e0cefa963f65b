"""Another commit's own benchmark, run beside this one (SPEC 18: speed as ratios measured side by side, since
this machine's absolute speed varies 3× between days).

``python experiments/bench.py --against 3c73d16 …`` checks the commit out in a detached ``git worktree``
(a scratch folder, removed afterwards), runs that commit's own ``experiments/bench.py`` there with the same
options, its own ``stslam`` first on the path, and writes its run folder beside this run's under
``--out-dir``; this run then compares itself with it (``--compare``).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

from stslam.errors import ConfigError

# The options a baseline run shares with this one: (option, takes a value). Every other option is this run's.
SHARED_OPTIONS = {"--seeds": True, "--sizes": True, "--repeats": True, "--worlds": True, "--frontend-frames": True,
                  "--skip-frontend": False, "--selection-only": False, "--skip-isam2": False}


def shared_arguments(args) -> list[str]:
    """The command-line options of parsed ``args`` (experiments/bench.py's) that a baseline run takes too."""
    out = []
    for option, takes_value in SHARED_OPTIONS.items():
        value = getattr(args, option[2:].replace("-", "_"))
        if not takes_value:
            out += [option] if value else []
        else:
            out += [option, *map(str, value if isinstance(value, (list, tuple)) else [value])]
    return out


def git(repo: Path, *args: str) -> str:
    """Output of ``git -C repo args`` (stripped); a ConfigError naming the command when it fails."""
    try:
        done = subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True, check=False)
    except FileNotFoundError as error:
        raise ConfigError("--against needs git on the PATH") from error
    if done.returncode != 0:
        raise ConfigError(f"git {' '.join(args)} failed in {repo}: {done.stderr.strip() or done.stdout.strip()}")
    return done.stdout.strip()


def run_baseline(commit: str, arguments: list[str], repo: Path, out_dir: Path) -> Path:
    """Run ``commit``'s own experiments/bench.py with ``arguments`` in a scratch worktree of ``repo``; its run
    folder (under ``out_dir``, made absolute) is returned. Its output goes to this process's stderr."""
    try:
        sha = git(repo, "rev-parse", "--verify", "--quiet", f"{commit}^{{commit}}")
    except ConfigError as error:
        raise ConfigError(f"--against {commit}: not a commit of the git repository {repo}") from error
    out_dir = Path(out_dir).resolve()
    with tempfile.TemporaryDirectory(prefix="stslam-baseline-") as scratch:
        tree = Path(scratch) / sha[:7]
        git(repo, "worktree", "add", "--detach", str(tree), sha)
        try:
            if not (tree / "experiments" / "bench.py").is_file():
                raise ConfigError(f"--against {commit}: that commit has no experiments/bench.py")
            before = set((out_dir / "bench").glob("*"))
            env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tree), os.environ.get("PYTHONPATH", "")])}
            command = [sys.executable, "experiments/bench.py", *arguments, "--out-dir", str(out_dir)]
            print(f"baseline: {commit} ({sha[:7]}) runs its own benchmark: {' '.join(command[1:])}", file=sys.stderr)
            done = subprocess.run(command, cwd=tree, env=env, stdout=sys.stderr, check=False)
            if done.returncode != 0:
                raise ConfigError(f"--against {commit}: its experiments/bench.py ended with exit code "
                                  f"{done.returncode} (its output is above)")
        finally:
            try:
                git(repo, "worktree", "remove", "--force", str(tree))
            except ConfigError as error:  # a warning: it must not hide the run's own error
                print(f"warning: the scratch worktree was not removed ({error}); `git worktree prune` clears "
                      f"its entry", file=sys.stderr)
    made = sorted(set((out_dir / "bench").glob("*")) - before)
    if len(made) != 1:
        raise ConfigError(f"--against {commit}: expected its run to write one folder under {out_dir / 'bench'}, "
                          f"found {len(made)}")
    return made[0]
