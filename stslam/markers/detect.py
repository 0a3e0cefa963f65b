"""Square fiducial markers found in an image with OpenCV's ArUco module (SPEC 17).

Dictionaries are named as OpenCV spells them (``DICT_6X6_250``,
``DICT_APRILTAG_36h11``, …; :data:`DICTIONARY_NAMES`). Corners come in
OpenCV's order: the marker's top-left, top-right, bottom-right, bottom-left
as printed, in pixels of the image as recorded (lens distortion not removed),
refined to sub-pixel accuracy.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from stslam.checks import check_choice, check_fields
from stslam.markers.corners import refine_corners

DICTIONARY_NAMES = tuple(sorted(name for name in dir(cv2.aruco) if name.startswith("DICT_")))
CORNER_REFINEMENTS = {"none": cv2.aruco.CORNER_REFINE_NONE, "subpix": cv2.aruco.CORNER_REFINE_SUBPIX,
                      "contour": cv2.aruco.CORNER_REFINE_CONTOUR, "apriltag": cv2.aruco.CORNER_REFINE_APRILTAG}


def check_dictionary_name(name) -> str:
    """``name`` if OpenCV has a predefined dictionary of that name, else ValueError listing some."""
    if not isinstance(name, str) or name not in DICTIONARY_NAMES:
        raise ValueError(f"expected an OpenCV dictionary name such as DICT_4X4_50, DICT_6X6_250, "
                         f"DICT_ARUCO_ORIGINAL or DICT_APRILTAG_36h11; got {name!r}")
    return name


def dictionary(name: str):
    """OpenCV's predefined dictionary called ``name`` (ValueError for an unknown name)."""
    return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, check_dictionary_name(name)))


@dataclass(frozen=True)
class DetectionSettings:
    """How markers are found: the dictionary, OpenCV's corner refinement and its window (px), the polygon
    tolerance (fraction of the perimeter; larger accepts blurred or distorted edges) and the smallest
    perimeter (fraction of the image's larger side); ``edge_refinement``: corners from the marker's edges
    (:mod:`stslam.markers.corners`, needs the camera) after OpenCV's."""

    dictionary: str = "DICT_6X6_250"
    corner_refinement: str = "subpix"
    refinement_window_px: int = 5
    polygon_tolerance: float = 0.05
    min_perimeter_rate: float = 0.02
    edge_refinement: bool = True

    def __post_init__(self):
        check_dictionary_name(self.dictionary)
        check_choice("corner_refinement", self.corner_refinement, tuple(CORNER_REFINEMENTS))
        check_fields(self, refinement_window_px="[1, 50]", polygon_tolerance="(0, 0.2]",
                     min_perimeter_rate="(0, 1)")


class MarkerDetector:
    """OpenCV's ``ArucoDetector`` with :class:`DetectionSettings`; ``detect`` is a function of the image alone.

    ``K`` (3, 3) and ``D`` (the lens distortion), when given, let ``edge_refinement`` work.
    """

    def __init__(self, settings: DetectionSettings = DetectionSettings(), K=None, D=None):
        parameters = cv2.aruco.DetectorParameters()
        parameters.cornerRefinementMethod = CORNER_REFINEMENTS[settings.corner_refinement]
        parameters.cornerRefinementWinSize = int(settings.refinement_window_px)
        parameters.polygonalApproxAccuracyRate = float(settings.polygon_tolerance)
        parameters.minMarkerPerimeterRate = float(settings.min_perimeter_rate)
        self.settings = settings
        chosen = dictionary(settings.dictionary)
        self._cells = int(chosen.markerSize) + 2  # the bits and the black border around them
        self._detector = cv2.aruco.ArucoDetector(chosen, parameters)
        self._camera = None if K is None or not settings.edge_refinement else (np.asarray(K, float),
                                                                                np.zeros(0) if D is None else D)

    def detect(self, image) -> dict[int, np.ndarray]:
        """Marker id → its corners (4, 2) px of a BGR (H, W, 3) or grey (H, W) uint8 image.

        An id seen twice in one image is ambiguous (which one is the door's?) and left out.
        """
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        corners, ids, _ = self._detector.detectMarkers(grey)
        if ids is None:
            return {}
        flat = [int(i) for i in np.asarray(ids).reshape(-1)]
        found = {i: np.asarray(c, dtype=float).reshape(4, 2) for i, c in zip(flat, corners) if flat.count(i) == 1}
        if self._camera is not None:
            found = {i: refine_corners(grey, c, *self._camera, self._cells) for i, c in found.items()}
        return found
