"""Images made smaller on conversion, and the K that describes them (SPEC 15).

A recording at 1280 × 720 or more costs the front end four times a 640 × 480
one and holds corners at a scale its settings were not chosen for; ``convert.py
width=640`` writes it smaller. With pixel centres at integer coordinates, a
point at (u, v) of the recorded image lies at u′ = s (u + ½) − ½ in an image
scaled by s, so f′ = s f and c′ = s (c + ½) − ½ per axis. Colour is averaged
over each output pixel's area (``cv2.INTER_AREA``); depth takes the recorded
value nearest each output pixel's centre (``cv2.INTER_NEAREST_EXACT``), so
no depth is made up across an edge and holes stay NaN.
"""

from __future__ import annotations

import cv2
import numpy as np

from stslam.errors import InputFileError


def scaled_intrinsics(K, sx: float, sy: float) -> np.ndarray:
    """K (3, 3) of images scaled by ``sx`` across and ``sy`` down: f′ = s f, c′ = s (c + ½) − ½ (module docstring)."""
    K = np.asarray(K, dtype=float)
    out = K.copy()
    out[0, :2] *= sx
    out[1, 1] *= sy
    out[0, 2] = sx * (K[0, 2] + 0.5) - 0.5
    out[1, 2] = sy * (K[1, 2] + 0.5) - 0.5
    return out


class Resize:
    """Images of ``size`` = (width, height) brought to ``width`` pixels across, the height in proportion
    (``active`` False, and images unchanged, for None or the same width)."""

    def __init__(self, size: tuple[int, int], width: int | None, path, topic: str):
        w, h = int(size[0]), int(size[1])
        self.active = width is not None and int(width) != w
        self.size = (w, h)
        if not self.active:
            return
        if w <= 0 or h <= 0:
            raise InputFileError(path, f"topic {topic}: width and height are 0; making the images {width} pixels "
                                       f"wide needs their size")
        if not 0 < int(width) < w:
            raise InputFileError(path, f"topic {topic}: the images are {w} pixels wide; width={width} must be "
                                       f"smaller (images are not enlarged)")
        self.size = (int(width), max(1, int(round(h * int(width) / w))))
        self.scale = (self.size[0] / w, self.size[1] / h)

    def K(self, K) -> np.ndarray:
        """Intrinsics of the resized images: f′ = s f, c′ = s (c + ½) − ½ per axis (module docstring)."""
        K = np.asarray(K, dtype=float)
        return scaled_intrinsics(K, *self.scale) if self.active else K

    def colour(self, image: np.ndarray) -> np.ndarray:
        return cv2.resize(image, self.size, interpolation=cv2.INTER_AREA) if self.active else image

    def depth(self, depth: np.ndarray) -> np.ndarray:
        return cv2.resize(depth, self.size, interpolation=cv2.INTER_NEAREST_EXACT) if self.active else depth
