"""A camera's calibration from a file: OpenCV's FileStorage XML or YAML, or a ROS ``camera_info`` YAML (SPEC 17).

Accepted layouts (keys as the tools write them):

* OpenCV ``cv2.FileStorage`` (``calibrateCamera`` samples, ``fs.write(...)``):
  ``camera_matrix`` (3 × 3) and ``distortion_coefficients`` (1 × n), as
  ``!!opencv-matrix`` nodes in YAML (headed ``%YAML:1.0`` or ``%YAML 1.2``) or
  ``type_id="opencv-matrix"`` elements in XML; ``image_width``, ``image_height``
  if present. ``cameraMatrix``/``distCoeffs`` and ``K``/``D`` are read as well.
* ROS 1 ``camera_info`` YAML (``camera_calibration``'s output): ``camera_matrix``
  and ``distortion_coefficients`` as ``{rows, cols, data}``, ``image_width``,
  ``image_height``, ``distortion_model``; a ROS 2 message dump (``k``, ``d``,
  ``width``, ``height``) as well.

Distortion coefficients are OpenCV's order (k1, k2, p1, p2[, k3[, k4, k5, k6[, s1…s4[, τx, τy]]]]);
absent coefficients mean none. A file without a camera matrix, or with one that
is not a finite 3 × 3 with positive focal lengths, is an
:class:`~stslam.errors.InputFileError` naming the file and what was expected.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import yaml

from stslam.errors import InputFileError
from stslam.io.resize import scaled_intrinsics

K_KEYS = ("camera_matrix", "cameraMatrix", "K", "k", "intrinsics")
D_KEYS = ("distortion_coefficients", "distCoeffs", "dist_coeffs", "D", "d")
SIZE_KEYS = (("image_width", "image_height"), ("width", "height"))
COEFFICIENT_COUNTS = (0, 4, 5, 8, 12, 14)  # the lengths cv2.solvePnP and cv2.projectPoints accept


@dataclass(frozen=True)
class CameraCalibration:
    """Intrinsics ``K`` (3, 3) px, distortion ``D`` (n,) in OpenCV's order, image ``size`` (width, height) or None."""

    K: np.ndarray
    D: np.ndarray
    size: tuple[int, int] | None
    path: str


class _OpenCvYamlLoader(yaml.SafeLoader):
    """PyYAML's safe loader that reads OpenCV's ``!!opencv-matrix`` nodes as plain mappings."""


_OpenCvYamlLoader.add_multi_constructor("tag:yaml.org,2002:opencv-",
                                        lambda loader, suffix, node: loader.construct_mapping(node, deep=True))


def _matrix(value, path, key: str) -> np.ndarray:
    """Numbers of a ``{rows, cols, data}`` mapping, a flat or nested list, or a FileStorage matrix."""
    if isinstance(value, dict):
        value = value.get("data")
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputFileError(path, f"{key}: expected a list of numbers, got {str(value)[:80]!r}") from None
    return array.reshape(-1)


def _first(mapping: dict, keys) -> tuple[str | None, object]:
    for key in keys:
        if key in mapping and mapping[key] is not None:
            return key, mapping[key]
    return None, None


def _read_yaml(text: str, path) -> dict:
    # OpenCV heads its YAML with "%YAML:1.0" (or "%YAML 1.2" since 5.0): a directive PyYAML refuses; drop it.
    body = re.sub(r"\A\s*%YAML[: ]\s*\d+\.\d+\s*\n", "", text)
    try:
        data = yaml.load(body, Loader=_OpenCvYamlLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None)
        line = None if mark is None else mark.line + 1
        raise InputFileError(path, f"not a calibration YAML file ({getattr(error, 'problem', None) or error})",
                             line) from None
    if not isinstance(data, dict):
        raise InputFileError(path, "expected a YAML mapping with camera_matrix and distortion_coefficients")
    return data


def _read_xml(path) -> dict:
    try:
        storage = cv2.FileStorage(str(path), cv2.FILE_STORAGE_READ)
    except cv2.error as error:
        raise InputFileError(path, f"not an OpenCV FileStorage XML file ({str(error).strip().splitlines()[-1]})") \
            from None
    data = {}
    for key in (*K_KEYS, *D_KEYS, *(k for pair in SIZE_KEYS for k in pair)):
        node = storage.getNode(key)
        if node.isNone():
            continue
        data[key] = node.mat() if node.isMap() else (node.real() if node.isReal() or node.isInt() else None)
    storage.release()
    return data


def read_camera_calibration(path) -> CameraCalibration:
    """The calibration in ``path`` (module docstring); InputFileError for a missing, unreadable or incomplete file."""
    file = Path(path)
    try:
        text = file.read_text(encoding="utf-8", errors="replace")
    except OSError as error:
        raise InputFileError(path, f"cannot be read: {error.strerror or error}") from None
    data = _read_xml(file) if text.lstrip().startswith("<") else _read_yaml(text, path)
    key, value = _first(data, K_KEYS)
    if key is None:
        raise InputFileError(path, f"no camera matrix; expected a 3 × 3 matrix under one of {', '.join(K_KEYS[:2])} "
                                   "(OpenCV FileStorage) or camera_matrix.data (ROS camera_info)")
    K = _matrix(value, path, key)
    if K.size != 9 or not np.all(np.isfinite(K)):
        raise InputFileError(path, f"{key}: expected 9 finite numbers (a 3 × 3 matrix), got {K.size}")
    K = K.reshape(3, 3)
    if K[0, 0] <= 0 or K[1, 1] <= 0 or not np.allclose(K[2], [0.0, 0.0, 1.0]):
        raise InputFileError(path, f"{key}: expected [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0, "
                                   f"got {K.tolist()}")
    d_key, d_value = _first(data, D_KEYS)
    D = np.zeros(0) if d_key is None else _matrix(d_value, path, d_key)
    if D.size not in COEFFICIENT_COUNTS or not np.all(np.isfinite(D)):
        raise InputFileError(path, f"{d_key}: expected {', '.join(map(str, COEFFICIENT_COUNTS[1:]))} finite "
                                   f"distortion coefficients (OpenCV's order), got {D.size}")
    size = None
    for w_key, h_key in SIZE_KEYS:
        if w_key in data and h_key in data:
            w, h = (_matrix(data[k], path, k) for k in (w_key, h_key))
            if w.size == 1 and h.size == 1 and w[0] > 0 and h[0] > 0:
                size = (int(w[0]), int(h[0]))
            break
    return CameraCalibration(K=K, D=D, size=size, path=str(path))


def scaled_to(calibration: CameraCalibration, width: int, height: int) -> CameraCalibration:
    """The calibration for frames of ``width`` × ``height`` px: itself when the size matches or is unknown,
    K scaled (f' = s f, c' = s (c + 1/2) − 1/2, pixel centres at integers) when the frames are the calibrated
    ones resized; InputFileError for frames of another shape (e.g. a portrait video of a landscape calibration)."""
    if calibration.size is None or calibration.size == (width, height):
        return calibration
    cw, ch = calibration.size
    sx, sy = width / cw, height / ch
    if abs(sx - sy) > 0.01 * max(sx, sy):
        raise InputFileError(calibration.path, f"calibrated for {cw} × {ch} px images, but the video's frames are "
                                               f"{width} × {height} px (another aspect ratio: rotated or cropped?); "
                                               "expected a calibration of this camera at the video's size")
    K = scaled_intrinsics(calibration.K, sx, sy)
    return CameraCalibration(K=K, D=calibration.D, size=(width, height), path=calibration.path)
