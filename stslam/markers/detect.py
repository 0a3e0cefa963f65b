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


# The second look for a marker the first missed: every bit error the dictionary can correct is corrected,
# more of each cell is read, and more threshold windows are tried (slower, and more tolerant).
SECOND_PASS = {"errorCorrectionRate": 1.0, "perspectiveRemoveIgnoredMarginPerCell": 0.3,
               "polygonalApproxAccuracyRate": 0.1, "maxErroneousBitsInBorderRate": 0.6}


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
    (:mod:`stslam.markers.corners`, needs the camera) after OpenCV's; ``second_pass``: a wanted marker not
    found is looked for again with :data:`SECOND_PASS` (blurred bits: measured on a motion-blurred rendered
    door, 37 of 90 frames found in one pass, 52 in two); ``fast_first_pass``: a first look searches a
    downscaled image (OpenCV's "ArUco3" mode: 2 ms instead of 12 ms a 640 × 480 frame here, the same markers
    found on a rendered door with a 60 px marker); when it finds no marker, or misses a wanted one, the
    full-size detection runs as well (a 30 px marker is lost by the downscaling)."""

    dictionary: str = "DICT_6X6_250"
    corner_refinement: str = "subpix"
    refinement_window_px: int = 5
    polygon_tolerance: float = 0.05
    min_perimeter_rate: float = 0.02
    edge_refinement: bool = True
    second_pass: bool = True
    fast_first_pass: bool = True

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
        self.settings = settings
        chosen = dictionary(settings.dictionary)
        self._cells = int(chosen.markerSize) + 2  # the bits and the black border around them
        self._fast = (cv2.aruco.ArucoDetector(chosen, self._parameters({"useAruco3Detection": True}))
                      if settings.fast_first_pass else None)
        self._detector = cv2.aruco.ArucoDetector(chosen, self._parameters({}))
        self._second = cv2.aruco.ArucoDetector(chosen, self._parameters(SECOND_PASS)) if settings.second_pass else None
        self._camera = None if K is None or not settings.edge_refinement else (np.asarray(K, float),
                                                                                np.zeros(0) if D is None else D)

    def _parameters(self, overrides: dict):
        parameters = cv2.aruco.DetectorParameters()
        parameters.cornerRefinementMethod = CORNER_REFINEMENTS[self.settings.corner_refinement]
        parameters.cornerRefinementWinSize = int(self.settings.refinement_window_px)
        parameters.polygonalApproxAccuracyRate = float(self.settings.polygon_tolerance)
        parameters.minMarkerPerimeterRate = float(self.settings.min_perimeter_rate)
        for name, value in overrides.items():
            setattr(parameters, name, value)
        return parameters

    @staticmethod
    def _unique(corners, ids) -> dict[int, np.ndarray]:
        """Id → corners (4, 2); an id seen twice in one image is ambiguous (which is the door's?) and left out."""
        if ids is None:
            return {}
        flat = [int(i) for i in np.asarray(ids).reshape(-1)]
        return {i: np.asarray(c, dtype=float).reshape(4, 2) for i, c in zip(flat, corners) if flat.count(i) == 1}

    def detect(self, image, wanted=()) -> dict[int, np.ndarray]:
        """Marker id → its corners (4, 2) px of a BGR (H, W, 3) or grey (H, W) uint8 image.

        The downscaled look first (``fast_first_pass``), the full-size one when it finds nothing or misses
        a ``wanted`` id, the tolerant one (``second_pass``) for wanted ids still missing, or for any id while
        nothing is wanted and nothing was found (the first sight of a marker not named); an id seen twice in
        one image is left out.
        """
        grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        found = self._unique(*self._fast.detectMarkers(grey)[:2]) if self._fast is not None else {}
        if self._fast is None or not found or set(wanted) - set(found):  # the full-size look
            found |= self._unique(*self._detector.detectMarkers(grey)[:2])
        missing = set(wanted) - set(found)
        if (missing or not (wanted or found)) and self._second is not None:
            again = self._unique(*self._second.detectMarkers(grey)[:2])
            found |= {i: c for i, c in again.items() if i in missing or not wanted}
        if self._camera is not None:
            found = {i: refine_corners(grey, c, *self._camera, self._cells) for i, c in found.items()}
        return found
