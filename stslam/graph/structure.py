"""An articulated landmark's structure correction δ as a graph variable: :mod:`stslam.articulation.correction`."""

from stslam.articulation.correction import SIZES, across, corrected_position, correction_size

__all__ = ["SIZES", "across", "corrected_position", "correction_size"]
