"""EKF SLAM with landmark blocks: the shared core, block kinds and filters (SPEC 6)."""

from stslam.slam.blocks import ArticulatedBlock, ConstantVelocityPointBlock, StaticPointBlock
from stslam.slam.core import SlamState
from stslam.slam.filters import FILTER_NAMES, FILTER_PARAMS, FilterSpec, FilterTrack, make_filter, run_filter

__all__ = [
    "ArticulatedBlock", "ConstantVelocityPointBlock", "StaticPointBlock", "SlamState",
    "FILTER_NAMES", "FILTER_PARAMS", "FilterSpec", "FilterTrack", "make_filter", "run_filter",
]
