"""The process's peak resident memory (the benchmark's ``peak_rss_mb``, SPEC 11).

Linux keeps it as ``VmHWM`` in ``/proc/self/status`` (proc(5)); elsewhere it is ``getrusage``'s
``ru_maxrss`` (kB on Linux, bytes on macOS).
"""

from __future__ import annotations

import resource
import sys
from pathlib import Path

STATUS = Path("/proc/self/status")


def peak_rss_mb(status: Path = STATUS) -> float:
    """Peak resident memory (MB) of this process so far."""
    try:
        for line in status.read_text(encoding="ascii").splitlines():
            if line.startswith("VmHWM:"):
                return int(line.split()[1]) / 1024.0  # kB
    except (OSError, ValueError, IndexError):
        pass
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / (1024.0 * 1024.0) if sys.platform == "darwin" else rss / 1024.0
