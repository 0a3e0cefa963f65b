"""The benchmark's peak memory (stslam.eval.memory)."""

from __future__ import annotations

import resource
import sys

import numpy as np
import pytest

from stslam.eval.memory import STATUS, peak_rss_mb


def _rusage_mb() -> float:
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return rss / 2**20 if sys.platform == "darwin" else rss / 1024.0


def test_the_peak_covers_a_fresh_allocation():
    block = np.ones(64 * 2**20 // 8)  # 64 MB, written, so resident
    assert peak_rss_mb() >= block.nbytes / 2**20  # the peak holds at least this block
    del block


@pytest.mark.skipif(not STATUS.exists(), reason="VmHWM is Linux's /proc")
def test_linuxs_high_water_mark_is_the_same_peak_getrusage_keeps():
    # Both count this process's largest resident size; they are sampled a moment apart and rounded to pages
    # differently, so 1 MB apart at most (the peak only grows, and nothing large is allocated between them).
    assert peak_rss_mb() == pytest.approx(_rusage_mb(), abs=1.0)


def test_without_a_status_file_the_peak_is_getrusages():
    assert peak_rss_mb(STATUS.parent / "no-such-status-file") == pytest.approx(_rusage_mb(), abs=1.0)
