"""Argument checks for settings dataclasses and algorithms: a ``ValueError`` naming the argument.

The config edge (:mod:`stslam.config.readers`) words its range errors the same
way, with the full config key and :class:`~stslam.errors.ConfigError`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from operator import attrgetter


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


def check_fields(settings, **intervals: str) -> None:
    """Check fields of ``settings`` against intervals such as ``"(0, 90]"`` or ``"[1, inf)"``.

    ``(``/``)`` exclude the bound, ``[``/``]`` include it, ``inf`` leaves that
    side unbounded; a field outside its interval is a ValueError naming it. A dotted
    name (``"motion.min_travel_m"``) is a field of a nested settings dataclass.
    """
    for name, interval in intervals.items():
        text = interval.strip()
        low_text, high_text = (part.strip() for part in text[1:-1].split(","))
        low = None if low_text in ("-inf", "") else float(low_text)
        high = None if high_text in ("inf", "") else float(high_text)
        check_number(name, attrgetter(name)(settings), low=low, high=high, low_open=text[0] == "(",
                     high_open=text[-1] == ")")


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
