"""stslam: spatiotemporal articulated models for dynamic SLAM.

The filters work on many small matrices (a few hundred states at most), where
a multi-threaded BLAS only adds synchronisation: on the 2-core reference
machine, OpenBLAS's default threads made one ``dynamic_slam`` seed 12× slower.
Importing stslam therefore defaults the BLAS and OpenMP thread counts to 1
(unless already set) — effective when stslam is imported before numpy, as the
entry scripts and the tests do. Set ``OPENBLAS_NUM_THREADS`` yourself to
override it.
"""

import os as _os

for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_MAX_THREADS"):
    _os.environ.setdefault(_name, "1")

__version__ = "0.1.0"
