"""Factor-graph back end: the SLAM state of :mod:`stslam.slam` held in a GTSAM iSAM2 smoother (SPEC 14).

gtsam is an optional dependency (``pip install -e ".[gtsam]"``); nothing here
imports it at package import time, so the rest of the library works without it.
"""
