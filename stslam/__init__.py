"""stslam: spatiotemporal articulated models for dynamic SLAM.

The filters work on many small matrices (a few hundred states at most), where
a multi-threaded BLAS only adds synchronisation: on the 2-core reference
machine, OpenBLAS's default threads made one ``dynamic_slam`` seed 12× slower.
Importing stslam therefore defaults the BLAS and OpenMP thread counts to 1
(unless already set) — effective when stslam is imported before numpy, as the
entry scripts and the tests do. Set ``OPENBLAS_NUM_THREADS`` yourself to
override it.

For the same reason of numbers, on an x86-64 processor with AVX2 and FMA it
defaults ``OPENBLAS_CORETYPE`` to ``Haswell``: OpenBLAS otherwise picks its
kernels by processor, and an AVX-512 machine's (SkylakeX) round differently,
so that the same config and seed gave other last digits there (every filter's
track), and A-SLAM's selector bank, written out to match the Haswell kernels'
arithmetic bit for bit, drifted from its one-by-one route by 3e-9 over 40
steps. With one kernel family, a run repeats to the bit on every such machine.
Set ``OPENBLAS_CORETYPE`` yourself to override it.
"""

import os as _os
import platform as _platform

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_MAX_THREADS"):
    _os.environ.setdefault(_name, "1")


def _has_avx2_fma() -> bool:
    """Whether this is an x86-64 processor whose flags (Linux /proc/cpuinfo) include AVX2 and FMA."""
    if _platform.machine().lower() not in ("x86_64", "amd64"):
        return False
    try:
        with open("/proc/cpuinfo", encoding="ascii", errors="replace") as cpuinfo:
            flags = next((line for line in cpuinfo if line.startswith("flags")), "")
    except OSError:
        return False
    return {"avx2", "fma"} <= set(flags.split())


if _has_avx2_fma():
    _os.environ.setdefault("OPENBLAS_CORETYPE", "Haswell")

__version__ = "0.1.0"
