"""Images of a camera with lens distortion turned into those of its ideal pinhole (SPEC 15).

The filters and the front end use the pinhole model of :mod:`stslam.robot.pinhole`
with the calibration's K alone. A recording whose CameraInfo has non-zero
distortion coefficients is therefore undistorted on conversion: each output
pixel (u, v) of the ideal camera with the same K takes the value at the
distorted position of its ray, d(K⁻¹ (u, v, 1)ᵀ) (OpenCV's model of
``plumb_bob``, 5 coefficients, and ``rational_polynomial``, 8;
``cv2.initUndistortRectifyMap``). Colour is interpolated bilinearly; depth
takes the nearest pixel, so that no depth is made up across an edge and a
pixel without a return stays NaN. Pixels whose ray falls outside the recorded
image are black (colour) or NaN (depth).
"""

from __future__ import annotations

import cv2
import numpy as np

from stslam.errors import InputFileError

__all__ = ["Undistortion", "SUPPORTED_MODELS"]

SUPPORTED_MODELS = {"plumb_bob": (4, 5), "rational_polynomial": (8,)}  # model → coefficient counts OpenCV takes


class Undistortion:
    """The undistortion of one camera's images (``active`` is False, and images pass unchanged, when its
    coefficients are all zero).

    Parameters
    ----------
    K : array (3, 3)
        Intrinsics, pixels; the ideal camera keeps them.
    model : str
        The CameraInfo's ``distortion_model``.
    D : array
        Its coefficients.
    size : (int, int)
        Width and height of the images.
    path, topic :
        The bag and the CameraInfo topic, named in errors.
    """

    def __init__(self, K, model: str, D, size: tuple[int, int], path, topic: str):
        D = np.asarray(D, dtype=float).reshape(-1)
        self.model = model
        self.active = bool(D.size) and bool(np.any(D != 0))
        self.size = (int(size[0]), int(size[1]))
        if not self.active:
            self._maps = None
            return
        if model not in SUPPORTED_MODELS or D.size not in SUPPORTED_MODELS[model] or not np.all(np.isfinite(D)):
            expected = ", ".join(f"{m} ({' or '.join(map(str, n))} coefficients)" for m, n in SUPPORTED_MODELS.items())
            raise InputFileError(path, f"topic {topic}: distortion model {model!r} with {D.size} coefficients "
                                       f"{D.tolist()} is not supported; expected {expected}, or all zero")
        if self.size[0] <= 0 or self.size[1] <= 0:
            raise InputFileError(path, f"topic {topic}: width and height are 0; undistorting the images needs "
                                       f"their size")
        K = np.asarray(K, dtype=float)
        self._maps = cv2.initUndistortRectifyMap(K, D, None, K, self.size, cv2.CV_32FC1)

    def _check(self, image: np.ndarray, what: str) -> None:
        if (image.shape[1], image.shape[0]) != self.size:
            raise ValueError(f"{what} image is {image.shape[1]} × {image.shape[0]}, its calibration "
                             f"{self.size[0]} × {self.size[1]}")

    def colour(self, rgb: np.ndarray) -> np.ndarray:
        """The ideal camera's colour image (H, W, 3) uint8: bilinear, black outside the recorded image."""
        if not self.active:
            return rgb
        self._check(rgb, "colour")
        return cv2.remap(rgb, *self._maps, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT,
                         borderValue=(0, 0, 0))

    def depth(self, depth_m: np.ndarray) -> np.ndarray:
        """The ideal camera's depth image (H, W) float32 m: nearest pixel, NaN outside or without a return."""
        if not self.active:
            return depth_m
        self._check(depth_m, "depth")
        return cv2.remap(np.asarray(depth_m, dtype=np.float32), *self._maps, interpolation=cv2.INTER_NEAREST,
                         borderMode=cv2.BORDER_CONSTANT, borderValue=float("nan"))
