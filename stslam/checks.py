"""Argument checks for settings dataclasses and algorithms: a ``ValueError`` naming the argument.

The config edge (:mod:`stslam.config.readers`) words its range errors the same
way, with the full config key and :class:`~stslam.errors.ConfigError`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence


def range_text(low=None, high=None, low_open: bool = False, high_open: bool = False) -> str:
    """``> 0 and ≤ 90``-style text of the bounds (empty without bounds)."""
    parts = []
    if low is not None:
        parts.append(f"{'>' if low_open else '≥'} {low}")
    if high is not None:
        parts.append(f"{'<' if high_open else '≤'} {high}")
    return " and ".join(parts)


def out_of_range(value, low=None, high=None, low_open: bool = False, high_open: bool = False) -> bool:
    """Whether ``value`` breaks a bound (open bounds exclude the bound itself)."""
    return bool((low is not None and (value <= low if low_open else value < low))
                or (high is not None and (value >= high if high_open else value > high)))


def check_number(name: str, value, *, low=None, high=None, low_open: bool = False,
                 high_open: bool = False) -> float:
    """``value`` as a finite float within the bounds, else ``ValueError("<name>: expected …")``."""
    bounds = range_text(low, high, low_open, high_open)
    wanted = f"a finite number {bounds}".rstrip()
    if isinstance(value, bool):
        raise ValueError(f"{name}: expected {wanted}, got {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected {wanted}, got {value!r}") from None
    if not math.isfinite(number) or out_of_range(number, low, high, low_open, high_open):
        raise ValueError(f"{name}: expected {wanted}, got {value!r}")
    return number


def check_int(name: str, value, *, low=None, high=None) -> int:
    """``value`` as an int (not a bool, not a float) within ``[low, high]``, else ``ValueError``."""
    if isinstance(value, bool) or not hasattr(value, "__index__") or out_of_range(value, low, high):
        raise ValueError(f"{name}: expected {f'an integer {range_text(low, high)}'.rstrip()}, got {value!r}")
    return int(value)


def check_choice(name: str, value, choices: Sequence[str]) -> str:
    """``value`` if it is one of ``choices``, else ``ValueError("<name>: expected one of …; got …")``."""
    if value not in choices:
        raise ValueError(f"{name}: expected one of {', '.join(choices)}; got {value!r}")
    return value
