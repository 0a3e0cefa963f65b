"""Progress bars for long loops (stderr, so they never mix with results)."""

from __future__ import annotations

import sys
from collections.abc import Iterable

from tqdm.auto import tqdm


def progress(items: Iterable, desc: str, total: int | None = None, enabled: bool = True):
    """Wrap ``items`` in a tqdm bar written to stderr; a no-op when disabled."""
    return tqdm(items, desc=desc, total=total, disable=not enabled, file=sys.stderr,
                dynamic_ncols=True, mininterval=0.5)


class _QuietBar(tqdm):
    """A bar without tqdm's monitor thread: a process that forks workers stays single-threaded."""

    monitor_interval = 0


def counter(desc: str, total: int, enabled: bool = True):
    """A bar advanced by hand (``.update(n)``), e.g. by finished seeds; a no-op when disabled."""
    return _QuietBar(desc=desc, total=total, disable=not enabled, file=sys.stderr,
                     dynamic_ncols=True, mininterval=0.5)
