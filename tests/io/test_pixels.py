"""Pixels of image messages (stslam.io.pixels): every raw colour and depth encoding and compressed depth,
each checked against bytes laid out by hand as the encoding's definition puts them."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from stslam.errors import InputFileError
from stslam.io import pixels


def _smooth_rgb(h=24, w=32) -> np.ndarray:
    """Strongly coloured, slowly varying: red rises left to right, green top to bottom, blue is constant,
    so a swapped channel or a misplaced Bayer site shows up as a large error."""
    y, x = np.mgrid[0:h, 0:w]
    return np.stack([40 + 5 * x, 60 + 4 * y, np.full_like(x, 200)], axis=-1).astype(np.uint8)


def _colour(raw: np.ndarray, encoding: str, pad: int = 0) -> np.ndarray:
    """Decode ``raw`` (H, W, bpp) uint8, each row followed by ``pad`` bytes of padding."""
    h, w = raw.shape[:2]
    rows = raw.reshape(h, -1)
    padded = np.hstack([rows, np.full((h, pad), 77, np.uint8)])
    return pixels.colour_from_raw(padded.tobytes(), w, h, padded.shape[1], encoding, "f.mcap", "/rgb")


@pytest.mark.parametrize("pad", [0, 5])
def test_byte_order_encodings_give_the_same_rgb(pad):
    rgb = _smooth_rgb()
    alpha = np.full(rgb.shape[:2] + (1,), 9, np.uint8)
    bgr = rgb[..., ::-1]
    cases = {"rgb8": rgb, "bgr8": bgr, "8UC3": bgr, "rgba8": np.dstack([rgb, alpha]),
             "bgra8": np.dstack([bgr, alpha]), "8UC4": np.dstack([bgr, alpha])}
    for encoding, raw in cases.items():
        np.testing.assert_array_equal(_colour(raw, encoding, pad), rgb, err_msg=encoding)
    grey = rgb[..., 1:2]
    for encoding in ("mono8", "8UC1"):
        np.testing.assert_array_equal(_colour(grey, encoding, pad), np.repeat(grey, 3, axis=2))


def _mosaic(rgb: np.ndarray, pattern: str) -> np.ndarray:
    """One byte per pixel: the colour the 2 × 2 ``pattern`` (e.g. "rggb", read row by row) puts there."""
    out = np.empty(rgb.shape[:2], np.uint8)
    for n, letter in enumerate(pattern):
        dy, dx = divmod(n, 2)
        out[dy::2, dx::2] = rgb[dy::2, dx::2, "rgb".index(letter)]
    return out[..., None]


@pytest.mark.parametrize("pattern", ["rggb", "bggr", "gbrg", "grbg"])
def test_bayer_mosaics_are_demosaiced_with_their_own_pattern(pattern):
    rgb = _smooth_rgb()
    got = _colour(_mosaic(rgb, pattern), f"bayer_{pattern}8").astype(int)
    inner = (slice(2, -2), slice(2, -2))
    # Bilinear demosaicing of a field that is linear in x and y is exact away from the border;
    # 1 level for rounding. A wrong pattern puts red where blue is: errors of ~100 levels.
    np.testing.assert_allclose(got[inner], rgb[inner], atol=1)
    for other in {"rggb", "bggr", "gbrg", "grbg"} - {pattern}:
        wrong = _colour(_mosaic(rgb, pattern), f"bayer_{other}8").astype(int)
        assert np.abs(wrong[inner] - rgb[inner]).max() > 50


def _yuv422(y: np.ndarray, u: int, v: int, order: str) -> np.ndarray:
    """Two bytes per pixel of a 4:2:2 image with luma ``y`` (H, W) and one chroma pair everywhere."""
    h, w = y.shape
    pairs = np.empty((h, w // 2, 4), np.uint8)
    layout = {"uyvy": ("u", "y0", "v", "y1"), "yuyv": ("y0", "u", "y1", "v")}[order]
    values = {"u": u, "v": v, "y0": y[:, 0::2], "y1": y[:, 1::2]}
    for n, name in enumerate(layout):
        pairs[..., n] = values[name]
    return pairs.reshape(h, w, 2)


@pytest.mark.parametrize("encoding,order", [("uyvy", "uyvy"), ("yuv422", "uyvy"), ("yuyv", "yuyv"),
                                            ("yuv422_yuy2", "yuyv")])
def test_yuv422_is_bt601_video_range_in_the_named_byte_order(encoding, order):
    y = np.tile(np.array([16, 60, 126, 235], np.uint8), (2, 2))  # (2, 8)
    grey = _colour(_yuv422(y, 128, 128, order), encoding).astype(float)
    # Neutral chroma: R = G = B = (Y − 16) · 255 / 219 (BT.601 video range); 1 level for rounding.
    expected = np.clip((y - 16.0) * 255.0 / 219.0, 0, 255)
    for channel in range(3):
        np.testing.assert_allclose(grey[..., channel], expected, atol=1)
    # Pure red in BT.601 video range is Y 81, Cb 90, Cr 240; swapping U and V would give blue.
    red = _colour(_yuv422(np.full((2, 4), 81, np.uint8), 90, 240, order), encoding).astype(int)
    np.testing.assert_allclose(red.reshape(-1, 3), np.tile([255, 0, 0], (8, 1)), atol=3)


def test_bad_colour_images_are_named():
    with pytest.raises(InputFileError, match=r"f\.mcap: topic /rgb: unsupported colour encoding 'rgb16'; "
                                             r"expected one of rgb8, bgr8"):
        pixels.colour_from_raw(b"\0" * 12, 2, 1, 12, "rgb16", "f.mcap", "/rgb")
    with pytest.raises(InputFileError, match=r"uyvy image holds pixel pairs; width 3 is odd"):
        pixels.colour_from_raw(b"\0" * 6, 3, 1, 6, "uyvy", "f.mcap", "/rgb")
    with pytest.raises(InputFileError, match=r"bgra8 image of 4 × 2 needs step ≥ 16 and 32 bytes, has step 16 "
                                             r"and 31 bytes"):
        pixels.colour_from_raw(b"\0" * 31, 4, 2, 16, "bgra8", "f.mcap", "/rgb")
    with pytest.raises(InputFileError, match=r"bayer_rggb8 mosaic needs at least 2 × 2 pixels"):
        pixels.colour_from_raw(b"\0" * 4, 4, 1, 4, "bayer_rggb8", "f.mcap", "/rgb")
    with pytest.raises(InputFileError, match=r"compressed image \(format 'jpeg'\) cannot be decoded"):
        pixels.colour_from_compressed(b"not a jpeg", "jpeg", "f.mcap", "/rgb")


def test_raw_depth_in_either_byte_order_and_unit():
    metres = np.array([[0.5, 2.0, 0.0], [np.nan, np.inf, 7.25]], np.float32)
    for big_endian, order in ((False, "<"), (True, ">")):
        got, source = pixels.depth_from_raw(metres.astype(f"{order}f4").tobytes(), 3, 2, 12, "32FC1", "f", "/d",
                                            big_endian=big_endian)
        assert source == "32FC1"
        np.testing.assert_array_equal(got, [[0.5, 2.0, np.nan], [np.nan, np.nan, 7.25]])
        mm = np.array([[500, 2000, 0], [1, 65535, 7250]], f"{order}u2")
        for encoding in ("16UC1", "mono16"):
            got, source = pixels.depth_from_raw(mm.tobytes(), 3, 2, 6, encoding, "f", "/d", big_endian=big_endian)
            assert source == "16UC1"
            np.testing.assert_allclose(got, [[0.5, 2.0, np.nan], [0.001, 65.535, 7.25]], rtol=1e-6)
    with pytest.raises(InputFileError, match=r"topic /d: unsupported depth encoding '32FC3'"):
        pixels.depth_from_raw(b"\0" * 12, 1, 1, 12, "32FC3", "f", "/d")


def _png(values: np.ndarray) -> bytes:
    ok, data = cv2.imencode(".png", values)
    assert ok
    return data.tobytes()


def test_compressed_depth_png_in_millimetres_and_quantised_inverse_depth():
    mm = np.array([[0, 1500], [2000, 65000]], np.uint16)
    for data, fmt in ((_png(mm), "png"), (b"\0" * 12 + _png(mm), "16UC1; compressedDepth png")):
        got, source = pixels.depth_from_compressed(data, fmt, "f", "/d")
        assert source == "16UC1"
        np.testing.assert_allclose(got, [[np.nan, 1.5], [2.0, 65.0]], rtol=1e-6)
    # image_transport's 32FC1 compressedDepth: v = a / d + b with a = q (q + 1), b = 1 − a / d_max
    # (q = 100, d_max = 10 m), rounded to 16 bits; v = 0 for no return. Rounding v by ½ moves d by
    # d² / (2a), 0.2 mm at 2 m and 1.2 mm at 5 m.
    a = 100.0 * 101.0
    b = 1.0 - a / 10.0
    depth = np.array([[0.0, 0.8], [2.0, 5.0]])
    v = np.where(depth > 0, np.rint(a / np.where(depth > 0, depth, 1.0) + b), 0).astype(np.uint16)
    header = np.array([0], "<i4").tobytes() + np.array([a, b], "<f4").tobytes()
    got, source = pixels.depth_from_compressed(header + _png(v), "32FC1; compressedDepth png", "f", "/d")
    assert source == "32FC1"
    np.testing.assert_allclose(got, [[np.nan, 0.8], [2.0, 5.0]], atol=1.3e-3)


def test_bad_compressed_depth_is_named():
    with pytest.raises(InputFileError, match=r"RVL\) is not read; record or republish"):
        pixels.depth_from_compressed(b"\0" * 40, "16UC1; compressedDepth rvl", "f", "/d")
    with pytest.raises(InputFileError, match=r"must be a 16-bit PNG in millimetres, got uint8"):
        pixels.depth_from_compressed(_png(np.zeros((2, 2), np.uint8)), "png", "f", "/d")
    with pytest.raises(InputFileError, match=r"cannot be decoded as a one-channel PNG"):
        pixels.depth_from_compressed(b"\0" * 12, "16UC1; compressedDepth png", "f", "/d")
