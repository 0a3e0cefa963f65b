"""What git knows about the code a results folder was made from.

A results folder records the short sha of the commit it was made at and whether
the work tree had uncommitted changes (``version.json``, :mod:`stslam.io.results`).
:func:`changed_since` compares files of that commit with the files on disk now, by
content (git blob ids), so an uncommitted edit counts as a change and a file
that commit did not have counts as changed.
"""

from __future__ import annotations

import subprocess
from pathlib import Path


def _git(root: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True, timeout=60)


def resolve_commit(root: Path, sha: str) -> str | None:
    """Full sha of commit ``sha`` in the repository at ``root``; None if git does not know it."""
    if not sha or not all(c in "0123456789abcdefABCDEF" for c in sha):
        return None  # "nogit", "?" …: no commit was recorded
    try:
        done = _git(root, "rev-parse", "--verify", "--quiet", f"{sha}^{{commit}}")
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 and done.stdout.strip() else None


def head_commit(root: Path) -> str | None:
    """Full sha of HEAD, None outside git."""
    try:
        done = _git(root, "rev-parse", "--verify", "--quiet", "HEAD")
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() if done.returncode == 0 and done.stdout.strip() else None


def blob_ids_at(root: Path, commit: str, paths: list[str]) -> dict[str, str]:
    """path → blob id of each of ``paths`` (relative to ``root``) in ``commit``; absent files are left out."""
    if not paths:
        return {}
    done = _git(root, "ls-tree", "-r", "--full-tree", commit, "--", *paths)
    if done.returncode != 0:
        raise OSError(f"git ls-tree {commit} failed in {root}: {done.stderr.strip()}")
    ids = {}
    for line in done.stdout.splitlines():
        meta, _, path = line.partition("\t")
        ids[path] = meta.split()[2]
    return ids


def blob_ids_now(root: Path, paths: list[str]) -> dict[str, str]:
    """path → blob id of each of ``paths`` as the file is on disk now (missing files left out)."""
    present = [p for p in paths if (root / p).is_file()]
    if not present:
        return {}
    done = _git(root, "hash-object", "--", *present)
    if done.returncode != 0:
        raise OSError(f"git hash-object failed in {root}: {done.stderr.strip()}")
    return dict(zip(present, done.stdout.split()))


def changed_since(root: Path, commit: str, paths: list[str]) -> list[str]:
    """The ``paths`` whose content on disk differs from ``commit`` (added, edited or removed), sorted."""
    before = blob_ids_at(root, commit, paths)
    now = blob_ids_now(root, paths)
    return sorted(p for p in paths if before.get(p) != now.get(p))


class ChangeCache:
    """:func:`changed_since` per (sha, paths), each git query made once; unknown shas give None.

    The files on disk are read once per (sha, paths): a cache answers for one moment, so make a new
    one after files change.
    """

    def __init__(self, root: Path):
        self.root = Path(root)
        self._commits: dict[str, str | None] = {}
        self._changes: dict[tuple[str, tuple[str, ...]], list[str]] = {}

    def changed(self, sha: str, paths: list[str]) -> list[str] | None:
        """Files of ``paths`` changed since commit ``sha``, or None when git does not know ``sha``."""
        if sha not in self._commits:
            self._commits[sha] = resolve_commit(self.root, sha)
        commit = self._commits[sha]
        if commit is None:
            return None
        key = (commit, tuple(paths))
        if key not in self._changes:
            self._changes[key] = changed_since(self.root, commit, list(paths))
        return self._changes[key]
