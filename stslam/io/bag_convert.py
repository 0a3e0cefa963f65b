"""A ROS 1 / ROS 2 bag to an MCAP with the SPEC 9 topics (SPEC 15): the work behind ``experiments/convert.py``.

Two passes over the bag (:mod:`stslam.io.rosbag_read`):

1. The small topics (camera info, odometry, TF, ground truth) are read into
   arrays and the stamps of the colour and depth images collected; each colour
   image is paired with the depth image nearest in stamp within
   ``max_depth_offset_s`` (a colour image without one is left out), and with
   the odometry pose interpolated at its stamp (linear in translation,
   spherical in rotation; end poses up to ``max_pose_offset_s`` outside the
   span, else the frame is left out). The camera mount is the TF chain from
   the base frame to the colour image's frame, from ``/tf_static`` (else the
   first ``/tf`` messages).
2. The images are decoded and written with the colour image's stamp: colour
   as ``rgb8``, depth in its source encoding (16UC1 mm or 32FC1 m); the pose
   topics at the same stamps; calibration and mount once, at the first frame.
   Depth images of a depth camera of their own (``topics.depth_info`` set) are
   first re-projected into the colour camera
   (:func:`stslam.io.depth_registration.register_depth`), the depth optical
   frame's pose in the colour one from the same TF as the mount. Images of a
   camera whose CameraInfo has non-zero distortion coefficients are first
   undistorted to its ideal pinhole (:mod:`stslam.io.undistort`); aligned depth
   takes the colour camera's.

The filters derive their controls from consecutive odometry poses and stamps
(:func:`stslam.rgbd.slam_inputs.odometry_controls`), so the odometry is kept
as poses. The output is written to a temporary file and moved into place
only when complete (:func:`stslam.io.mcap_write.atomic_output`).
"""

from __future__ import annotations

import bisect
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from stslam.errors import InputFileError
from stslam.geometry import pose_matrix
from stslam.io import mcap_topics as mt
from stslam.io import rosbag_read as rb
from stslam.io.depth_registration import register_depth
from stslam.io.mcap_write import (ProtobufMcapWriter, atomic_output, calibration_message, depth_image_message,
                                  rgb_image_message, stamp_ns, transform_message)
from stslam.io.pose_track import PoseTrack
from stslam.io.resize import Resize
from stslam.io.tum import read_tum
from stslam.io.undistort import Undistortion
from stslam.progress import progress


TOPIC_KEYS = ("rgb", "depth", "camera_info", "odometry", "tf_static", "tf", "ground_truth", "depth_info")
OPTIONAL_TOPICS = ("tf", "ground_truth", "depth_info")


@dataclass(frozen=True)
class BagTopics:
    """Topic names in the bag (defaults: a RealSense camera on a wheeled robot, SPEC 15).

    ``ground_truth``, ``tf`` and ``depth_info`` may be ``None``; the others are required. ``depth_info``
    (the depth camera's CameraInfo) says that the depth images are the depth camera's own, not aligned to
    colour: they are then re-projected into the colour camera (:mod:`stslam.io.depth_registration`).
    """

    rgb: str = "/camera/color/image_raw"
    depth: str = "/camera/aligned_depth_to_color/image_raw"
    camera_info: str = "/camera/color/camera_info"
    odometry: str = "/odom"
    tf_static: str = "/tf_static"
    tf: str | None = "/tf"
    ground_truth: str | None = "/mocap/base"
    depth_info: str | None = None


@dataclass(frozen=True)
class ConvertSettings:
    """What to convert and how.

    Attributes
    ----------
    bag : str
        A ROS 1 ``.bag`` file or a ROS 2 bag folder (sqlite3 or MCAP storage).
    out : str
        The MCAP to write (SPEC 9 topics).
    overwrite : bool
        Replace an existing ``out``.
    topics : BagTopics
    base_frame : str
        The robot's body frame; the camera mount is the TF chain from it to the colour image's frame.
    camera_frame : str or None
        Frame of the colour images (None: the ``frame_id`` of their headers).
    ground_truth_tum : str or None
        A TUM file with the robot's true poses (instead of a ground-truth topic).
    max_depth_offset_s : float
        Largest stamp difference between a colour image and its depth image (s).
    max_pose_offset_s : float
        How far outside the odometry or ground truth time span a frame may lie and still take its end pose (s).
    stamps : str
        Each message's time: ``"header"`` (its header's stamp, the sensor's time) or ``"receive"`` (when the
        bag recorded it; for publishers that leave the stamp at 0). A TUM ground truth must be on that clock.
    unordered : str
        A message whose time does not increase on its topic (a repeated frame, one out of order): ``"error"``
        stops, ``"drop"`` leaves it out and counts it in the report.
    mount : tuple of 7 floats or None
        x, y, z (m), qx, qy, qz, qw: the colour camera's optical frame in the base frame, for a bag without
        the mount in TF (None: from ``/tf_static``, then ``/tf``).
    width : int or None
        Write the images this many pixels wide, the height in proportion (:mod:`stslam.io.resize`; None: as
        recorded).
    progress : bool
    """

    bag: str
    out: str
    overwrite: bool = False
    topics: BagTopics = BagTopics()
    base_frame: str = "base_link"
    camera_frame: str | None = None
    ground_truth_tum: str | None = None
    max_depth_offset_s: float = 0.02
    max_pose_offset_s: float = 0.05
    stamps: str = "header"
    unordered: str = "error"
    mount: tuple[float, ...] | None = None
    width: int | None = None
    progress: bool = False


@dataclass(frozen=True)
class ConvertReport:
    """What was converted: output path, frames written, colour images left out and why, ground truth source."""

    path: Path
    n_frames: int
    no_depth: int
    no_odometry: int
    ground_truth: str
    undistorted: str = ""
    unordered: tuple[tuple[str, int], ...] = ()

    def lines(self) -> list[str]:
        left = (f"; left out {self.no_depth} colour image(s) without depth, {self.no_odometry} outside the "
                f"odometry" if self.no_depth or self.no_odometry else "")
        fixed = f"; undistorted: {self.undistorted}" if self.undistorted else ""
        lines = [f"wrote {self.path}: {self.n_frames} frames{left}; ground truth: {self.ground_truth}{fixed}"]
        if self.unordered:
            lines.append("left out for stamps that did not increase: "
                         + ", ".join(f"{n} on {topic}" for topic, n in self.unordered))
        return lines


def _pose_track(reader, path, topic: str, connections, stamps: rb.Stamps) -> PoseTrack:
    times, poses = [], []
    for _, msgtype, msg, received_ns in rb.messages(reader, path, connections):
        t = stamps.of(topic, msg, received_ns)
        if t is not None:
            times.append(t)
            poses.append(rb.pose_of(msg, msgtype, path, topic))
    if not times:
        raise InputFileError(path, f"topic {topic}: no messages")
    return PoseTrack(times, poses)


def _tum_track(path: str) -> PoseTrack:
    rows = read_tum(path)
    poses = [pose_matrix(Rotation.from_quat(r[4:8]).as_matrix(), r[1:4]) for r in rows]
    return PoseTrack(rows[:, 0], poses)


def _image_stamps(reader, path, connections, stamps: rb.Stamps) -> list[float | None]:
    """Per image message in bag order, its time, or None for one left out (``unordered=drop``)."""
    out = []
    for topic, _, msg, received_ns in rb.messages(reader, path, connections):
        out.append(stamps.of(topic, msg, received_ns))
    if not out:
        raise InputFileError(path, f"topic {connections[0].topic}: no messages")
    return out


def _mount(reader, path, settings: ConvertSettings, camera_frame: str) -> np.ndarray:
    topics = settings.topics
    edges: dict = {}
    hint = (f"; a mount known otherwise is given as mount=[x,y,z,qx,qy,qz,qw], the optical frame in "
            f"{settings.base_frame}")
    for name, required in ((topics.tf_static, True), (topics.tf, False)):
        try:
            connections = rb.connections_of(reader, path, name, (rb.TF,), required) if name is not None else []
        except InputFileError as error:
            raise InputFileError(path, f"{error.problem}{hint}") from None
        if not connections:
            continue
        for _, _, msg, _ in rb.messages(reader, path, connections):
            for child, edge in rb.tf_edges(msg, path, name).items():
                edges.setdefault(child, edge)
        T = rb.chain(edges, settings.base_frame, camera_frame)
        if T is not None:
            return T
    searched = " and ".join(t for t in (topics.tf_static, topics.tf) if t)
    raise InputFileError(path, f"topic {topics.tf_static}: no transform chain {settings.base_frame} → "
                               f"{camera_frame} in {searched} (frames seen: {', '.join(sorted(edges)) or 'none'})"
                               f"{hint}")


def _given_mount(mount) -> np.ndarray:
    """4 × 4 pose of ``mount`` = (x, y, z, qx, qy, qz, qw); the quaternion is normalised."""
    values = np.asarray(mount, dtype=float)
    return pose_matrix(Rotation.from_quat(values[3:] / np.linalg.norm(values[3:])).as_matrix(), values[:3])


def _pairs(rgb_times, depth_times, tolerance: float) -> list[int | None]:
    """Per colour image, the index of the nearest depth image within ``tolerance`` (else None); images
    whose time is None (left out) pair with nothing."""
    index = [j for j, t in enumerate(depth_times) if t is not None]  # increasing times
    times = [depth_times[j] for j in index]
    out = []
    for t in rgb_times:
        if t is None:
            out.append(None)
            continue
        j = bisect.bisect_left(times, t)
        best = min((k for k in (j - 1, j) if 0 <= k < len(times)), key=lambda k: abs(times[k] - t), default=None)
        out.append(index[best] if best is not None and abs(times[best] - t) <= tolerance else None)
    return out


def _first(reader, path, connections):
    for _, msgtype, msg, _ in rb.messages(reader, path, connections):
        return msgtype, msg
    raise InputFileError(path, f"topic {connections[0].topic}: no messages")


@dataclass(frozen=True)
class _Registration:
    """The depth camera's intrinsics, image size and pose in the colour camera, and the colour size."""

    K_depth: np.ndarray
    depth_size: tuple[int, int]
    T_color_depth: np.ndarray
    K_color: np.ndarray
    color_size: tuple[int, int]
    frame: str
    info_topic: str
    undistortion: Undistortion

    def apply(self, depth: np.ndarray, path, topic: str) -> np.ndarray:
        size = (depth.shape[1], depth.shape[0])
        if self.depth_size not in ((0, 0), size):
            raise InputFileError(path, f"topic {self.info_topic}: calibration is for {self.depth_size[0]} × "
                                       f"{self.depth_size[1]} depth images but {topic} is {size[0]} × {size[1]}")
        return register_depth(self.undistortion.depth(depth), self.K_depth, self.K_color, self.T_color_depth,
                              self.color_size)


def _registration(reader, path, settings: ConvertSettings, depth_c, K_color, color_size, T_base_camera):
    """How to bring the depth images into the colour camera, or None when they are aligned already."""
    topic = settings.topics.depth_info
    if topic is None:
        return None
    if color_size == (0, 0):
        raise InputFileError(path, f"topic {settings.topics.camera_info}: width and height are 0; registering the "
                                   f"depth images into the colour camera needs the colour image size")
    _, info = _first(reader, path, rb.connections_of(reader, path, topic, (rb.CAMERA_INFO,)))
    K_depth, width, height = rb.intrinsics_of(info, path, topic)
    _, first_depth = _first(reader, path, depth_c)
    frame = first_depth.header.frame_id.lstrip("/")
    T_color_depth = np.linalg.inv(T_base_camera) @ _mount(reader, path, settings, frame)
    undistortion = Undistortion(K_depth, *rb.distortion_of(info), (width, height), path, topic)
    return _Registration(K_depth, (width, height), T_color_depth, K_color, color_size, frame, topic, undistortion)


def _undistorted(colour: Undistortion, registration: _Registration | None) -> str:
    """Which images were undistorted, with which model ("" for none)."""
    done = [f"colour ({colour.model})"] if colour.active else []
    if registration is not None and registration.undistortion.active:
        done.append(f"depth ({registration.undistortion.model})")
    return ", ".join(done)


def convert_bag(settings: ConvertSettings) -> ConvertReport:
    """Convert ``settings.bag`` to ``settings.out`` (see the module docstring)."""
    out, path, topics = Path(settings.out), settings.bag, settings.topics
    if out.exists() and not settings.overwrite:
        raise InputFileError(out, "already exists; pass overwrite=true to replace it")
    with rb.open_bag(path) as reader:
        rgb_c = rb.connections_of(reader, path, topics.rgb, rb.IMAGE_TYPES)
        depth_c = rb.connections_of(reader, path, topics.depth, rb.IMAGE_TYPES)
        info_c = rb.connections_of(reader, path, topics.camera_info, (rb.CAMERA_INFO,))
        odom_c = rb.connections_of(reader, path, topics.odometry, (rb.ODOMETRY,))
        truth_c = (rb.connections_of(reader, path, topics.ground_truth, rb.GROUND_TRUTH_TYPES, required=False)
                   if topics.ground_truth else [])
        stamps = rb.Stamps(path, settings.stamps, settings.unordered)
        rgb_times = _image_stamps(reader, path, rgb_c, stamps)
        depth_times = _image_stamps(reader, path, depth_c, stamps)
        _, info = _first(reader, path, info_c)
        K, info_w, info_h = rb.intrinsics_of(info, path, topics.camera_info)
        colour_fix = Undistortion(K, *rb.distortion_of(info), (info_w, info_h), path, topics.camera_info)
        resize = Resize((info_w, info_h), settings.width, path, topics.camera_info)
        odometry = _pose_track(reader, path, topics.odometry, odom_c, stamps)
        truth, truth_text = None, "none"
        if truth_c:
            truth, truth_text = _pose_track(reader, path, topics.ground_truth, truth_c, stamps), topics.ground_truth
        elif settings.ground_truth_tum:
            truth, truth_text = _tum_track(settings.ground_truth_tum), settings.ground_truth_tum
        _, first_rgb = _first(reader, path, rgb_c)
        camera_frame = settings.camera_frame or first_rgb.header.frame_id.lstrip("/")
        T_base_camera = (_given_mount(settings.mount) if settings.mount is not None
                         else _mount(reader, path, settings, camera_frame))

        registration = _registration(reader, path, settings, depth_c, K, (info_w, info_h), T_base_camera)
        undistorted = _undistorted(colour_fix, registration)

        pairs = _pairs(rgb_times, depth_times, settings.max_depth_offset_s)
        odom_at = [odometry.at(t, settings.max_pose_offset_s) if t is not None else None for t in rgb_times]
        keep = [j is not None and T is not None for j, T in zip(pairs, odom_at, strict=True)]
        if not any(keep):
            raise InputFileError(path, f"topic {topics.depth}: no colour image of {topics.rgb} has a depth image "
                                       f"within {settings.max_depth_offset_s} s and odometry from {topics.odometry}")
        wanted: dict[int, list[int]] = {}
        for i, j in enumerate(pairs):
            if keep[i]:
                wanted.setdefault(j, []).append(i)
        first = keep.index(True)
        sizes: dict = {}

        def check_size(topic, shape):
            size = (shape[1], shape[0])
            expected = sizes.setdefault("image", size)
            if size != expected:
                raise InputFileError(path, f"topic {topic}: image is {size[0]} × {size[1]} but the first "
                                           f"{topics.rgb} image is {expected[0]} × {expected[1]}")
            if (info_w, info_h) not in ((0, 0), size):
                raise InputFileError(path, f"topic {topics.camera_info}: calibration is for {info_w} × {info_h} "
                                           f"images but {topic} is {size[0]} × {size[1]}")

        with atomic_output(out, settings.overwrite) as handle:
            writer = ProtobufMcapWriter(handle)
            t0 = stamp_ns(rgb_times[first])
            writer.write(mt.DEFAULT_TOPICS.camera_mount,
                         transform_message(T_base_camera, mt.BASE_FRAME, mt.CAMERA_FRAME, t0), t0)
            writer.write(mt.DEFAULT_TOPICS.calibration, calibration_message(resize.K(K), *resize.size, t0), t0)
            i_rgb = j_depth = 0
            for topic, msgtype, msg, _ in progress(rb.messages(reader, path, rgb_c + depth_c), "convert",
                                                total=len(rgb_times) + len(depth_times), enabled=settings.progress):
                if topic == topics.rgb:
                    i, i_rgb = i_rgb, i_rgb + 1
                    if not keep[i]:
                        continue
                    rgb = rb.colour_of(msg, msgtype, path, topic)
                    check_size(topic, rgb.shape)
                    rgb = resize.colour(colour_fix.colour(rgb))
                    t_ns = stamp_ns(rgb_times[i])
                    writer.write(mt.DEFAULT_TOPICS.rgb, rgb_image_message(rgb, t_ns), t_ns)
                    writer.write(mt.DEFAULT_TOPICS.odometry,
                                 transform_message(odom_at[i], mt.WORLD_FRAME, mt.ODOM_BASE_FRAME, t_ns), t_ns)
                    T_true = truth.at(rgb_times[i], settings.max_pose_offset_s) if truth is not None else None
                    if T_true is not None:
                        writer.write(mt.DEFAULT_TOPICS.ground_truth_base,
                                     transform_message(T_true, mt.WORLD_FRAME, mt.BASE_FRAME, t_ns), t_ns)
                else:
                    j, j_depth = j_depth, j_depth + 1
                    if j not in wanted:
                        continue
                    depth, encoding = rb.depth_of(msg, msgtype, path, topic)
                    if registration is None:  # aligned depth has the colour camera's size and distortion
                        check_size(topic, depth.shape)
                        depth = colour_fix.depth(depth)
                    else:  # into the colour camera's ideal pinhole, at its size
                        depth = registration.apply(depth, path, topic)
                    depth = resize.depth(depth)
                    for i in wanted[j]:
                        t_ns = stamp_ns(rgb_times[i])
                        writer.write(mt.DEFAULT_TOPICS.depth, depth_image_message(depth, t_ns, encoding), t_ns)
            writer.add_metadata("stslam.convert", {"bag": str(path), "ground_truth": truth_text,
                                                   "camera_frame": camera_frame, "base_frame": settings.base_frame,
                                                   "depth": "aligned" if registration is None else
                                                   f"registered from {registration.frame}",
                                                   "undistorted": undistorted, "stamps": settings.stamps,
                                                   "unordered": settings.unordered,
                                                   "mount": "TF" if settings.mount is None else "given",
                                                   "size": "{}x{}".format(*resize.size)})
            writer.finish()
    return ConvertReport(path=out, n_frames=sum(keep),
                         no_depth=sum(j is None and t is not None for j, t in zip(pairs, rgb_times, strict=True)),
                         no_odometry=sum(j is not None and T is None for j, T in zip(pairs, odom_at, strict=True)),
                         ground_truth=truth_text, undistorted=undistorted,
                         unordered=tuple(sorted(stamps.dropped.items())))
