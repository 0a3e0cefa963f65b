"""The SLAM back end of ``dynamic_slam`` and ``fridge``: ``backend`` and the ``isam2`` settings (SPEC 14).

``backend: ekf`` (default) runs every filter on the EKF core
(:class:`stslam.slam.core.SlamState`); ``backend: isam2`` on the GTSAM iSAM2
smoother (:mod:`stslam.graph`), which needs the optional extra
``pip install -e ".[gtsam]"``. The ``isam2`` block (all optional):

* ``relinearize_threshold`` (> 0, default 0.01) and ``relinearize_skip`` (≥ 1, default 1): iSAM2's;
* ``floor_sigma`` (> 0, default 1e-4, m / rad): std added to singular factor covariances;
* ``final_iterations`` (≥ 0, default 3): extra iSAM2 updates after the last frame;
* ``factorization`` (``qr`` default, or ``cholesky``).
"""

from __future__ import annotations

from collections.abc import Mapping

from stslam.config.readers import get_choice, get_float, get_int

BACKENDS = ("ekf", "isam2")


def backend_name(cfg: Mapping) -> str:
    """``backend``: ``ekf`` (default) or ``isam2``."""
    return get_choice(cfg, "backend", BACKENDS, default="ekf")


def isam2_options(cfg: Mapping) -> dict:
    """Checked ``isam2.*`` values as keyword arguments of :class:`stslam.graph.state.Isam2Settings`."""
    return {
        "relinearize_threshold": get_float(cfg, "isam2.relinearize_threshold", low=0.0, low_open=True, default=0.01),
        "relinearize_skip": get_int(cfg, "isam2.relinearize_skip", low=1, default=1),
        "floor_sigma": get_float(cfg, "isam2.floor_sigma", low=0.0, low_open=True, default=1e-4),
        "final_iterations": get_int(cfg, "isam2.final_iterations", low=0, high=100, default=3),
        "factorization": get_choice(cfg, "isam2.factorization", ("qr", "cholesky"), default="qr"),
    }
