"""Undistortion of a recording's images to the ideal pinhole camera (SPEC 15)."""

from __future__ import annotations

import numpy as np
import pytest
from bag_writer import distort_image

from stslam.errors import InputFileError
from stslam.io.undistort import Undistortion

K = np.array([[60.0, 0.0, 31.5], [0.0, 60.0, 23.5], [0.0, 0.0, 1.0]])  # 64 × 48
D = np.array([-0.15, 0.04, 0.001, -0.001, 0.0])  # plumb_bob: barrel distortion, a RealSense-like size


def _ideal_colour() -> np.ndarray:
    """A smooth test image (gradients and a slow wave), so that two bilinear resamplings stay close."""
    v, u = np.mgrid[0:48, 0:64].astype(float)
    return np.stack([2 * u + 40, 3 * v + 30, 100 + 60 * np.sin(u / 9) * np.cos(v / 7)], axis=-1).astype(np.uint8)


def test_zero_coefficients_leave_images_as_they_are():
    fix = Undistortion(K, "plumb_bob", np.zeros(5), (64, 48), "bag", "/info")
    image, depth = _ideal_colour(), np.ones((48, 64), np.float32)
    assert not fix.active and fix.colour(image) is image and fix.depth(depth) is depth


def test_a_distorted_image_comes_back_to_the_ideal_one():
    """Recorded through the lens (corners moved by about 2 px), the image is up to 9 grey levels off the
    ideal one; undistorted, within 2 (two bilinear resamplings of a smooth image, each rounded to a level)."""
    ideal = _ideal_colour()
    recorded = distort_image(ideal, K, D)
    before = np.abs(recorded[6:-6, 6:-6].astype(int) - ideal[6:-6, 6:-6])
    assert before.max() >= 5 and before.mean() >= 0.5  # the lens matters here
    fixed = Undistortion(K, "plumb_bob", D, (64, 48), "bag", "/info").colour(recorded)
    after = np.abs(fixed[6:-6, 6:-6].astype(int) - ideal[6:-6, 6:-6])
    assert after.max() <= 2 and after.mean() <= 0.1


def test_depth_takes_the_nearest_pixel_and_keeps_holes():
    v, u = np.mgrid[0:48, 0:64]
    ideal = (1.0 + 0.01 * u + 0.02 * v).astype(np.float32)
    ideal[20:24, 30:34] = np.nan
    recorded = distort_image(ideal, K, D, nearest=True)
    fixed = Undistortion(K, "plumb_bob", D, (64, 48), "bag", "/info").depth(recorded)
    values = set(np.unique(recorded[np.isfinite(recorded)]).tolist())
    assert set(np.unique(fixed[np.isfinite(fixed)]).tolist()) <= values  # no depth made up between pixels
    middle = np.isfinite(ideal[6:-6, 6:-6])
    # Nearest twice: at most one pixel off in each direction, 0.03 m on this slope.
    assert np.nanmax(np.abs(fixed[6:-6, 6:-6] - ideal[6:-6, 6:-6])[middle]) <= 0.0301
    assert np.isnan(fixed[21, 31])


@pytest.mark.parametrize("model,coefficients", [("equidistant", [0.1, 0.01, 0.0, 0.0]), ("plumb_bob", [0.1, 0.2]),
                                                ("plumb_bob", [np.nan, 0, 0, 0, 0])])
def test_unsupported_distortion_is_named(model, coefficients):
    with pytest.raises(InputFileError, match=rf"bag: topic /info: distortion model '{model}' with "
                                             rf"{len(coefficients)} coefficients .* not supported; expected plumb_bob"):
        Undistortion(K, model, coefficients, (64, 48), "bag", "/info")


def _mcap_with_lens(path, model: str, coefficients) -> tuple[np.ndarray, np.ndarray]:
    """A 3-frame SPEC 9 MCAP whose calibration has the given distortion and whose images went through it;
    returns the ideal colour and depth images."""
    from stslam.io import mcap_topics as mt
    from stslam.io.mcap_write import (ProtobufMcapWriter, atomic_output, calibration_message, depth_image_message,
                                      rgb_image_message, stamp_ns)
    v, u = np.mgrid[0:48, 0:64]
    colour, depth = _ideal_colour(), (1.0 + 0.01 * u + 0.02 * v).astype(np.float32)
    D = np.asarray(coefficients, dtype=float)
    recorded = (distort_image(colour, K, D[:5]), distort_image(depth, K, D[:5], nearest=True)) if model == "plumb_bob" \
        else (colour, depth)
    with atomic_output(path) as handle:
        writer = ProtobufMcapWriter(handle)
        for k in range(3):
            t_ns = stamp_ns(k / 30)
            calibration = calibration_message(K, 64, 48, t_ns)
            calibration.distortion_model = model
            del calibration.D[:]
            calibration.D.extend(D.tolist())
            writer.write(mt.DEFAULT_TOPICS.calibration, calibration, t_ns)
            writer.write(mt.DEFAULT_TOPICS.rgb, rgb_image_message(recorded[0], t_ns), t_ns)
            writer.write(mt.DEFAULT_TOPICS.depth, depth_image_message(recorded[1], t_ns), t_ns)
        writer.finish()
    return colour, depth


def test_the_mcap_reader_undistorts_a_calibration_with_distortion(tmp_path):
    from stslam.io.mcap_read import read_rgbd_frames

    colour, depth = _mcap_with_lens(tmp_path / "lens.mcap", "plumb_bob", D)
    frames = list(read_rgbd_frames(tmp_path / "lens.mcap"))
    assert len(frames) == 3
    for frame in frames:  # the same bounds as the class's own tests above
        assert np.abs(frame.rgb[6:-6, 6:-6].astype(int) - colour[6:-6, 6:-6]).max() <= 2
        assert np.nanmax(np.abs(frame.depth_m[6:-6, 6:-6] - depth[6:-6, 6:-6])) <= 0.0301
    _mcap_with_lens(tmp_path / "fisheye.mcap", "equidistant", [0.1, 0.01, 0.0, 0.0])
    with pytest.raises(InputFileError, match=r"fisheye\.mcap: topic /camera/calibration: distortion model "
                                             r"'equidistant'"):
        list(read_rgbd_frames(tmp_path / "fisheye.mcap"))
