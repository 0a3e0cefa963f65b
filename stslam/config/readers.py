"""Checked access to values of the composed configuration (a plain nested dict).

The entry script converts Hydra's config to a dict; these helpers read a
dotted key and raise :class:`~stslam.errors.ConfigError` naming the key and
what was expected. :func:`field_default` gives a settings dataclass's default
for a key a config may leave out, so that default is stated only in the dataclass.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import Any

from stslam.checks import out_of_range, range_text
from stslam.errors import ConfigError

_MISSING = object()


def lookup(cfg: Mapping, key: str, default: Any = _MISSING) -> Any:
    """Value at dotted ``key`` (``"robot.alpha"``); ``default`` if given and absent."""
    node: Any = cfg
    for part in key.split("."):
        if isinstance(node, Mapping) and part in node:
            node = node[part]
        elif default is not _MISSING:
            return default
        else:
            raise ConfigError(f"{key}: missing from the configuration")
    return node


def _check_range(key, value, what, low, high, low_open, high_open):
    if out_of_range(value, low, high, low_open, high_open):
        raise ConfigError(f"{key}: expected {what} {range_text(low, high, low_open, high_open)}, got {value!r}")


def get_int(cfg: Mapping, key: str, *, low=None, high=None, default: Any = _MISSING) -> int:
    """Integer at ``key`` within ``[low, high]`` (bools are rejected)."""
    value = lookup(cfg, key, default)
    if isinstance(value, bool) or not isinstance(value, int):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise ConfigError(f"{key}: expected an integer, got {value!r}")
    _check_range(key, value, "an integer", low, high, False, False)
    return value


def get_float(
    cfg: Mapping,
    key: str,
    *,
    low=None,
    high=None,
    low_open: bool = False,
    high_open: bool = False,
    default: Any = _MISSING,
) -> float:
    """Finite float at ``key`` within the given (open or closed) bounds."""
    value = lookup(cfg, key, default)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{key}: expected a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(f"{key}: expected a finite number, got {value!r}")
    _check_range(key, value, "a number", low, high, low_open, high_open)
    return value


def get_positive(cfg: Mapping, key: str, *, default: Any = _MISSING) -> float:
    """Finite float > 0 at ``key``: a standard deviation σ (m, rad), a time step δt (s) …"""
    return get_float(cfg, key, low=0.0, low_open=True, default=default)


def get_probability(cfg: Mapping, key: str, *, default: Any = _MISSING) -> float:
    """Probability strictly inside (0, 1) at ``key``, e.g. the selection threshold τ (SPEC 4)."""
    value = get_float(cfg, key, default=default)
    _check_range(key, value, "a probability", 0.0, 1.0, True, True)
    return value


def get_bool(cfg: Mapping, key: str, default: Any = _MISSING) -> bool:
    """Boolean at ``key``."""
    value = lookup(cfg, key, default)
    if not isinstance(value, bool):
        raise ConfigError(f"{key}: expected true or false, got {value!r}")
    return value


def get_optional(read, cfg: Mapping, key: str, **checks) -> Any:
    """``read(cfg, key, **checks)`` (``get_float``, ``get_int`` …), or None when ``key`` is absent or null."""
    return None if lookup(cfg, key, None) is None else read(cfg, key, **checks)


def get_choice(cfg: Mapping, key: str, choices: Sequence[str], default: Any = _MISSING) -> str:
    """String at ``key`` that must be one of ``choices``."""
    value = lookup(cfg, key, default)
    if value not in choices:
        raise ConfigError(f"{key}: expected one of {', '.join(map(str, choices))}; got {value!r}")
    return value


def get_float_list(cfg: Mapping, key: str, *, length: int | None = None, low=None,
                   default: Any = _MISSING) -> list[float]:
    """List of finite floats at ``key`` (optionally of fixed length, each ≥ ``low``)."""
    value = lookup(cfg, key, default)
    if isinstance(value, (str, bytes)) or not isinstance(value, Sequence):
        raise ConfigError(f"{key}: expected a list of numbers, got {value!r}")
    if length is not None and len(value) != length:
        raise ConfigError(f"{key}: expected {length} numbers, got {len(value)}")
    out = []
    for i, item in enumerate(value):
        if isinstance(item, bool) or not isinstance(item, (int, float)) or not math.isfinite(item):
            raise ConfigError(f"{key}[{i}]: expected a finite number, got {item!r}")
        _check_range(f"{key}[{i}]", float(item), "a number", low, None, False, False)
        out.append(float(item))
    return out


def field_default(cls, name: str) -> Any:
    """Default of field ``name`` of dataclass ``cls`` (for a key the config may omit)."""
    field = {f.name: f for f in dataclasses.fields(cls)}[name]
    if field.default is not dataclasses.MISSING:
        return field.default
    if field.default_factory is not dataclasses.MISSING:
        return field.default_factory()
    raise TypeError(f"{cls.__name__}.{name} has no default")


def optional_block(cfg: Mapping, key: str, names, what: str) -> bool:
    """Whether the options block at ``key`` is given (null or absent: False).

    A block that is not a mapping, or holds a key not in ``names`` (the options it
    may set), is a ConfigError naming ``key`` (``what`` says what the block holds).
    """
    block = lookup(cfg, key, None)
    if block is None:
        return False
    if not isinstance(block, Mapping):
        raise ConfigError(f"{key}: expected {what} or null, got {block!r}")
    unknown = sorted(set(block) - set(names))
    if unknown:
        raise ConfigError(f"{key}: unknown option(s) {', '.join(map(str, unknown))}")
    return True


def get_name_list(cfg: Mapping, key: str, choices: Sequence[str]) -> list[str]:
    """Non-empty list at ``key`` of distinct names from ``choices`` (e.g. ``methods``)."""
    value = lookup(cfg, key)
    if isinstance(value, (str, bytes)) or not isinstance(value, (list, tuple)) or not value:
        raise ConfigError(f"{key}: expected a non-empty list of names from {', '.join(choices)}, got {value!r}")
    for i, name in enumerate(value):
        if name not in choices:
            raise ConfigError(f"{key}[{i}]: expected one of {', '.join(choices)}; got {name!r}")
        if name in value[:i]:
            raise ConfigError(f"{key}[{i}]: {name} is listed twice")
    return list(value)


@dataclasses.dataclass(frozen=True)
class RunSettings:
    """What every experiment run has (SPEC 12): base ``seed``, ``n_seeds`` (seed k uses seed + k), ``progress``."""

    seed: int
    n_seeds: int
    progress: bool = False


def run_settings(cfg: Mapping) -> RunSettings:
    """``seed`` (≥ 0), ``n_seeds`` (≥ 1) and ``progress`` (default false) of an experiment's config."""
    return RunSettings(get_int(cfg, "seed", low=0), get_int(cfg, "n_seeds", low=1),
                       get_bool(cfg, "progress", default=False))
