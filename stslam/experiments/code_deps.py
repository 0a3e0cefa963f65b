"""The source files a run's results depend on, found by reading the imports.

A run of experiment ``<exp>`` executes ``experiments/run.py``, which imports
:mod:`stslam.experiments.runner`, which loads ``stslam.experiments.<exp>``. Its
results depend on those files and on every module of the package they import,
directly or through other modules of the package: imports inside functions
count, and importing ``stslam.a.b`` also runs ``stslam/__init__.py`` and
``stslam/a/__init__.py``. The imports are read from the source (``ast``), not by
importing it, so the answer is that of the files on disk. Imports made by name
at run time (``importlib.import_module``) are not followed; the experiment
module, the one loaded that way, is a starting file instead.

Configuration files are not code dependencies: the resolved configuration a run
wrote is compared instead (:mod:`stslam.experiments.reproduce`).
"""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = "stslam"
RUN_SCRIPT = "experiments/run.py"
RUNNER = "stslam/experiments/runner.py"


def _module_file(root: Path, dotted: str) -> str | None:
    """Repository-relative file of module or package ``dotted``, None if it is not in the package."""
    parts = dotted.split(".")
    if parts[0] != PACKAGE:
        return None
    base = root.joinpath(*parts)
    if (base / "__init__.py").is_file():
        return (base / "__init__.py").relative_to(root).as_posix()
    if base.with_suffix(".py").is_file():
        return base.with_suffix(".py").relative_to(root).as_posix()
    return None


def _with_parents(root: Path, dotted: str) -> list[str]:
    """Files that ``import dotted`` executes: each enclosing package's ``__init__.py``, then the module."""
    parts = dotted.split(".")
    files = [_module_file(root, ".".join(parts[:i])) for i in range(1, len(parts) + 1)]
    return [f for f in files if f is not None]


def _package_of(relative: str) -> list[str]:
    """Parts of the package holding the module file ``relative`` (``a/b.py`` and ``a/__init__.py``: a)."""
    parts = Path(relative).with_suffix("").parts
    return list(parts[:-1])


def imported_files(root: Path, relative: str) -> set[str]:
    """Package files imported anywhere in the source file ``relative`` (relative to ``root``)."""
    tree = ast.parse((root / relative).read_text(encoding="utf-8"), filename=relative)
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                found.update(_with_parents(root, alias.name))
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative: level 1 is the file's own package (for __init__.py too)
                package = _package_of(relative)
                base = package[:len(package) - (node.level - 1)]
                dotted = ".".join(base + ([node.module] if node.module else []))
            else:
                dotted = node.module or ""
            found.update(_with_parents(root, dotted))
            for alias in node.names:  # `from pkg import module` imports the module too
                sub = _module_file(root, f"{dotted}.{alias.name}") if dotted else None
                if sub is not None:
                    found.update(_with_parents(root, f"{dotted}.{alias.name}"))
    return found


def import_closure(root: Path, start: list[str]) -> list[str]:
    """``start`` files and every package file they import, transitively; sorted, relative to ``root``."""
    root = Path(root)
    seen: set[str] = set()
    todo = list(start)
    while todo:
        relative = todo.pop()
        if relative in seen:
            continue
        seen.add(relative)
        todo.extend(imported_files(root, relative) - seen)
    return sorted(seen)


def experiment_dependencies(root: Path, exp: str, extra_scripts: tuple[str, ...] = ()) -> list[str]:
    """Files a run of ``exp`` depends on: the run script, the runner, ``stslam/experiments/<exp>.py``,
    ``extra_scripts`` (a data step's script) and everything they import from the package."""
    start = [RUN_SCRIPT, RUNNER, f"{PACKAGE}/experiments/{exp}.py", *extra_scripts]
    missing = [f for f in start if not (Path(root) / f).is_file()]
    if missing:
        raise FileNotFoundError(f"{', '.join(missing)}: not found under {root}")
    return import_closure(root, start)
