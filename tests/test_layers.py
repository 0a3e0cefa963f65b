"""The package layers of docs/architecture.md, checked on every module's imports."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "stslam"

# Layer of each package or top-level module (docs/architecture.md): imports go to the same or a lower layer.
LAYERS = {
    "errors": 0, "progress": 0, "output": 0, "geometry": 0, "checks": 0,
    "eval": 1, "io": 1.5,
    "kalman": 2, "robot": 2, "markers": 2,
    "articulation": 3,
    "selection": 4,
    "sim": 5,
    "slam": 6, "graph": 6,
    "rgbd": 7,
    "render": 8,
    "config": 9,
    "experiments": 10,
}
CONFIG_EDGE = ("config", "experiments")
MAX_TOP_LEVEL_MODULES = 6
MAX_LINES = 400


def _modules():
    return sorted(p for p in PACKAGE.rglob("*.py"))


def _unit(path: Path) -> str:
    """Package (or top-level module) a file belongs to."""
    return path.relative_to(PACKAGE).with_suffix("").parts[0]


def _imported_names(path: Path) -> set[str]:
    """Absolute module names a file imports (``from stslam import x`` counts as ``stslam.x``)."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.update([node.module] if node.module != "stslam" else [f"stslam.{a.name}" for a in node.names])
        elif isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
    return names


def _imported_units(path: Path) -> set[str]:
    """stslam packages and top-level modules a file imports."""
    return {n.split(".")[1] for n in _imported_names(path) if n.startswith("stslam.")}


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_imports_go_down_the_layers(path):
    unit = _unit(path)
    if unit == "__init__":
        return
    assert unit in LAYERS, f"{path}: package {unit!r} has no layer in docs/architecture.md"
    above = {u for u in _imported_units(path) - {unit} if LAYERS[u] > LAYERS[unit]}
    assert not above, f"{path} ({unit}, layer {LAYERS[unit]}) imports higher layers: {sorted(above)}"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_only_the_config_edge_reads_the_config(path):
    if _unit(path) in CONFIG_EDGE:
        return
    assert "config" not in _imported_units(path), f"{path} imports stslam.config"
    foreign = {name.split(".")[0] for name in _imported_names(path)} & {"hydra", "omegaconf"}
    assert not foreign, f"{path} imports {sorted(foreign)}"
    assert "DictConfig" not in path.read_text(), f"{path} mentions DictConfig"


def test_module_count_and_size():
    top = [p for p in PACKAGE.glob("*.py") if p.name != "__init__.py"]
    assert len(top) <= MAX_TOP_LEVEL_MODULES, sorted(p.name for p in top)
    long = {str(p.relative_to(PACKAGE)): n for p in _modules() if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines: {long}"


@pytest.mark.parametrize("path", _modules(), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_algorithms_raise_value_errors_not_config_errors(path):
    """ConfigError (a user's bad config key) belongs to the config edge; algorithms raise ValueError."""
    if _unit(path) in CONFIG_EDGE or path.name == "errors.py":
        return
    imported = {alias.name for node in ast.walk(ast.parse(path.read_text()))
                if isinstance(node, ast.ImportFrom) for alias in node.names}
    assert "ConfigError" not in imported, f"{path} imports ConfigError"
