"""Pixels of image messages, for every reader: raw encodings and compressed images (SPEC 9, 15).

One decoder for the images of ROS bags (``sensor_msgs/Image`` and
``CompressedImage``) and of MCAP files (``foxglove.RawImage`` and
``foxglove.CompressedImage``), so that a recording reads the same whichever
container it came in. Colour comes out as uint8 (H, W, 3) RGB; depth as float32
(H, W) metres along the optical axis with NaN where the sensor has no return
(0, negative and non-finite values are read as no return).

Raw colour encodings are the ones both message types name (ROS
``image_encodings``, Foxglove's RawImage list): ``rgb8``, ``bgr8``, ``8UC3`` (as
OpenCV stores it, BGR), ``rgba8``, ``bgra8``, ``mono8``, ``8UC1``, the four 8-bit
Bayer mosaics ``bayer_rggb8`` … (demosaiced bilinearly, the pattern naming the
colours of the top-left 2 × 2 block) and 4:2:2 YUV, ``uyvy`` (ROS ``yuv422``) and
``yuyv`` (ROS ``yuv422_yuy2``), read as BT.601 with the video range Y 16–235.
Raw depth: ``32FC1`` metres, ``16UC1`` and ``mono16`` millimetres. Compressed
colour is anything OpenCV reads (JPEG, PNG, WebP, …); compressed depth is a
16-bit PNG in millimetres or image_transport's ``compressedDepth`` (PNG after a
12-byte header; ``32FC1`` ones hold quantised inverse depth).
"""

from __future__ import annotations

import cv2
import numpy as np

from stslam.errors import InputFileError

# encoding → (bytes per pixel, OpenCV conversion to RGB or None when the bytes already are RGB)
COLOUR_ENCODINGS: dict[str, tuple[int, int | None]] = {
    "rgb8": (3, None),
    "bgr8": (3, cv2.COLOR_BGR2RGB),
    "8UC3": (3, cv2.COLOR_BGR2RGB),
    "rgba8": (4, cv2.COLOR_RGBA2RGB),
    "bgra8": (4, cv2.COLOR_BGRA2RGB),
    "8UC4": (4, cv2.COLOR_BGRA2RGB),
    "mono8": (1, cv2.COLOR_GRAY2RGB),
    "8UC1": (1, cv2.COLOR_GRAY2RGB),
    "bayer_rggb8": (1, cv2.COLOR_BayerRGGB2RGB),
    "bayer_bggr8": (1, cv2.COLOR_BayerBGGR2RGB),
    "bayer_gbrg8": (1, cv2.COLOR_BayerGBRG2RGB),
    "bayer_grbg8": (1, cv2.COLOR_BayerGRBG2RGB),
    "uyvy": (2, cv2.COLOR_YUV2RGB_UYVY),
    "yuv422": (2, cv2.COLOR_YUV2RGB_UYVY),
    "yuyv": (2, cv2.COLOR_YUV2RGB_YUYV),
    "yuv422_yuy2": (2, cv2.COLOR_YUV2RGB_YUYV),
}
# encoding → (bytes per pixel, metres per unit, the source encoding it is reported as, which a converted file
# keeps); 32FC1 holds metres, the 16-bit ones millimetres.
DEPTH_ENCODINGS: dict[str, tuple[int, float, str]] = {"32FC1": (4, 1.0, "32FC1"), "16UC1": (2, 1e-3, "16UC1"),
                                                      "mono16": (2, 1e-3, "16UC1")}
# image_transport's compressedDepth header: int32 format, then two float32 quantisation parameters.
COMPRESSED_DEPTH_HEADER_BYTES = 12


def _rows(data, width: int, height: int, step: int, encoding: str, bytes_per_pixel: int, path,
          topic: str) -> np.ndarray:
    """Pixel bytes (H, W·bpp) of a raw image, row padding removed, after checking its sizes."""
    w, h, step = int(width), int(height), int(step)
    buffer = _buffer(data)
    if w <= 0 or h <= 0:
        raise InputFileError(path, f"topic {topic}: {encoding} image of size {w} × {h}")
    if step < w * bytes_per_pixel or buffer.size < step * h:
        raise InputFileError(path, f"topic {topic}: {encoding} image of {w} × {h} needs step ≥ "
                                   f"{w * bytes_per_pixel} and {step * h} bytes, has step {step} and "
                                   f"{buffer.size} bytes")
    return buffer[:step * h].reshape(h, step)[:, :w * bytes_per_pixel]


def colour_from_raw(data, width: int, height: int, step: int, encoding: str, path, topic: str) -> np.ndarray:
    """uint8 (H, W, 3) RGB of a raw colour image (module docstring for the encodings)."""
    known = COLOUR_ENCODINGS.get(encoding)
    if known is None:
        raise InputFileError(path, f"topic {topic}: unsupported colour encoding {encoding!r}; expected one of "
                                   f"{', '.join(COLOUR_ENCODINGS)}")
    bytes_per_pixel, conversion = known
    if bytes_per_pixel == 2 and int(width) % 2:
        raise InputFileError(path, f"topic {topic}: a {encoding} image holds pixel pairs; width {width} is odd")
    if encoding.startswith("bayer") and (int(width) < 2 or int(height) < 2):
        raise InputFileError(path, f"topic {topic}: a {encoding} mosaic needs at least 2 × 2 pixels, "
                                   f"got {width} × {height}")
    rows = _rows(data, width, height, step, encoding, bytes_per_pixel, path, topic)
    pixels = np.ascontiguousarray(rows).reshape(int(height), int(width), bytes_per_pixel)
    if conversion is None:
        return pixels
    return cv2.cvtColor(pixels[..., 0] if bytes_per_pixel == 1 else pixels, conversion)


def depth_from_raw(data, width: int, height: int, step: int, encoding: str, path, topic: str,
                   big_endian: bool = False) -> tuple[np.ndarray, str]:
    """Depth (H, W) float32 metres of a raw depth image and its source encoding (``32FC1`` or ``16UC1``)."""
    known = DEPTH_ENCODINGS.get(encoding)
    if known is None:
        raise InputFileError(path, f"topic {topic}: unsupported depth encoding {encoding!r}; expected one of "
                                   f"{', '.join(DEPTH_ENCODINGS)} (32FC1 in m, the others in mm)")
    size, scale, source = known
    rows = np.ascontiguousarray(_rows(data, width, height, step, encoding, size, path, topic))
    order = ">" if big_endian else "<"
    values = rows.view(f"{order}f4" if size == 4 else f"{order}u2").reshape(int(height), int(width))
    depth = values.astype(np.float32)
    if scale != 1.0:
        depth *= np.float32(scale)
    return _holes_as_nan(depth), source


def colour_from_compressed(data, fmt: str, path, topic: str) -> np.ndarray:
    """uint8 (H, W, 3) RGB of a compressed colour image (JPEG, PNG, … anything OpenCV reads)."""
    pixels = cv2.imdecode(_buffer(data), cv2.IMREAD_COLOR)
    if pixels is None:
        raise InputFileError(path, f"topic {topic}: compressed image (format {fmt!r}) cannot be decoded")
    return cv2.cvtColor(pixels, cv2.COLOR_BGR2RGB)


def depth_from_compressed(data, fmt: str, path, topic: str) -> tuple[np.ndarray, str]:
    """Depth (H, W) float32 metres of a 16-bit PNG (mm) or a ``compressedDepth`` image, and its source encoding."""
    buffer = _buffer(data)
    header = None
    if "compresseddepth" in fmt.lower():
        if "rvl" in fmt.lower():
            raise InputFileError(path, f"topic {topic}: compressed depth format {fmt!r} (RVL) is not read; "
                                       f"record or republish the depth as PNG compressedDepth or raw 16UC1")
        header, buffer = buffer[:COMPRESSED_DEPTH_HEADER_BYTES], buffer[COMPRESSED_DEPTH_HEADER_BYTES:]
    image = cv2.imdecode(buffer, cv2.IMREAD_UNCHANGED) if buffer.size else None
    if image is None or image.ndim != 2:
        raise InputFileError(path, f"topic {topic}: compressed depth (format {fmt!r}) cannot be decoded as a "
                                   f"one-channel PNG")
    if header is not None and "32FC1" in fmt:
        # Quantised inverse depth: depth = a / (v − b), v = 0 for no return.
        a, b = np.frombuffer(header[4:12].tobytes(), dtype="<f4")
        values = image.astype(np.float32)
        with np.errstate(divide="ignore", invalid="ignore"):
            depth = np.where(values > 0, a / (values - b), np.nan).astype(np.float32)
        return _holes_as_nan(depth), "32FC1"
    if image.dtype != np.uint16:
        raise InputFileError(path, f"topic {topic}: compressed depth (format {fmt!r}) must be a 16-bit PNG in "
                                   f"millimetres, got {image.dtype} pixels")
    return _holes_as_nan(image.astype(np.float32) * np.float32(1e-3)), "16UC1"


def _buffer(data) -> np.ndarray:
    """The bytes of a message's ``data`` (bytes from protobuf, a uint8 array from rosbags) as a flat uint8 array."""
    if isinstance(data, (bytes, bytearray, memoryview)):
        return np.frombuffer(data, dtype=np.uint8)
    return np.asarray(data, dtype=np.uint8).reshape(-1)


def _holes_as_nan(depth: np.ndarray) -> np.ndarray:
    depth[~(np.isfinite(depth) & (depth > 0))] = np.nan
    return depth
