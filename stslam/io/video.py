"""Video files: frames read one at a time, and frames written (SPEC 17).

Reading goes through OpenCV's FFmpeg back end (``cv2.VideoCapture``): MP4/MOV
(H.264, HEVC), AVI (MJPG), MKV … as FFmpeg decodes them, in display orientation
(OpenCV applies a phone video's rotation tag). Frames are BGR uint8
(H, W, 3), as OpenCV gives them. A file that does not exist, cannot be opened
as a video, or yields no frame is an :class:`~stslam.errors.InputFileError`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from stslam.errors import InputFileError

DEFAULT_FPS = 30.0  # when the container states no frame rate


@dataclass(frozen=True)
class VideoInfo:
    """What the container says: frame rate (Hz; ``DEFAULT_FPS`` if it says none), frame count (an estimate; 0 if
    unknown), frame size (width, height) px."""

    fps: float
    frame_count: int
    size: tuple[int, int]


class VideoFrames:
    """The frames of a video file, read one at a time (never all in memory).

    ``info`` is read on opening; iterating yields BGR uint8 frames (H, W, 3). A file with no frame at all is
    an InputFileError when the iteration ends.
    """

    def __init__(self, path):
        self.path = str(path)
        if not Path(path).is_file():
            raise InputFileError(path, "no such video file")
        capture = cv2.VideoCapture(self.path)
        opened = capture.isOpened()
        fps = capture.get(cv2.CAP_PROP_FPS) if opened else 0.0
        count = capture.get(cv2.CAP_PROP_FRAME_COUNT) if opened else 0.0
        size = (int(capture.get(cv2.CAP_PROP_FRAME_WIDTH)), int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT)))
        capture.release()
        if not opened:
            raise InputFileError(path, "cannot be read as a video (FFmpeg could not open it); expected e.g. "
                                       "an MP4, MOV or AVI file")
        self.info = VideoInfo(fps=float(fps) if math.isfinite(fps) and fps > 0 else DEFAULT_FPS,
                              frame_count=int(count) if math.isfinite(count) and count > 0 else 0, size=size)

    def __iter__(self) -> Iterator[np.ndarray]:
        capture = cv2.VideoCapture(self.path)
        n = 0
        try:
            while True:
                ok, frame = capture.read()
                if not ok or frame is None:
                    break
                if frame.ndim == 2:
                    frame = cv2.cvtColor(frame, cv2.COLOR_GRAY2BGR)
                n += 1
                yield frame
        finally:
            capture.release()
        if n == 0:
            raise InputFileError(self.path, "the video has no frames that can be decoded")


def write_video(path, frames_bgr: Iterable[np.ndarray], fps: float, fourcc: str = "MJPG") -> int:
    """Write BGR uint8 frames (H, W, 3), all of one size, to ``path``; returns the number written.

    MJPG in an AVI container is what this machine's OpenCV writes everywhere (no licensed encoder needed).
    """
    writer = None
    n = 0
    try:
        for frame in frames_bgr:
            frame = np.ascontiguousarray(frame, dtype=np.uint8)
            if writer is None:
                Path(path).parent.mkdir(parents=True, exist_ok=True)
                writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*fourcc), float(fps),
                                         (frame.shape[1], frame.shape[0]))
                if not writer.isOpened():
                    raise OSError(f"{path}: OpenCV cannot write {fourcc} video here")
            writer.write(frame)
            n += 1
    finally:
        if writer is not None:
            writer.release()
    return n
