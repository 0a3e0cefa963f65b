"""Test helper: a ROS 1 or ROS 2 bag with the default topics of conf/convert.yaml from an RGB-D MCAP (SPEC 15).

Frames of a SPEC 9 recording (:class:`stslam.io.mcap_read.RGBDMcapReader`) are
written with the ``rosbags`` writers as a RealSense on a wheeled robot would
publish them: colour (``bgr8`` raw, or JPEG), aligned depth (the recording's
metres as 32FC1, or 16UC1 millimetres / PNG), camera info, odometry of
base_link in odom, the camera mount on /tf_static (base_link → camera_link →
camera_color_optical_frame), and optionally ground truth (PoseStamped) on /mocap/base.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from stslam.io.depth_registration import register_depth
from stslam.io.mcap_read import RGBDMcapReader

LINK_FRAME = "camera_link"
OPTICAL_FRAME = "camera_color_optical_frame"
DEPTH_FRAME = "camera_depth_optical_frame"


def distort_image(image: np.ndarray, K, D, nearest: bool = False) -> np.ndarray:
    """What a camera with distortion D records of the ideal pinhole image ``image`` (same K): each recorded
    pixel takes the ideal image at its undistorted position (OpenCV's model; bilinear, or nearest)."""
    h, w = image.shape[:2]
    pixels = np.stack(np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32)), axis=-1)
    ideal = cv2.undistortPoints(pixels.reshape(-1, 1, 2), np.asarray(K, float), np.asarray(D, float),
                                P=np.asarray(K, float)).reshape(h, w, 2)
    interpolation = cv2.INTER_NEAREST if nearest else cv2.INTER_LINEAR
    border = float("nan") if nearest else 0
    return cv2.remap(image, ideal[..., 0], ideal[..., 1], interpolation=interpolation,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=border)


class _Messages:
    def __init__(self, typestore, ros: int):
        self.ts, self.ros, self.T = typestore, ros, typestore.types

    def header(self, t_ns: int, frame: str):
        time = self.T["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=t_ns % 10**9)
        if self.ros == 1:
            return self.T["std_msgs/msg/Header"](seq=0, stamp=time, frame_id=frame)
        return self.T["std_msgs/msg/Header"](stamp=time, frame_id=frame)

    def image(self, t_ns, frame, pixels: np.ndarray, encoding: str):
        h, w = pixels.shape[:2]
        data = np.frombuffer(np.ascontiguousarray(pixels).tobytes(), dtype=np.uint8)
        return self.T["sensor_msgs/msg/Image"](header=self.header(t_ns, frame), height=h, width=w, encoding=encoding,
                                               is_bigendian=0, step=data.size // h, data=data)

    def compressed(self, t_ns, frame, data: bytes, fmt: str):
        return self.T["sensor_msgs/msg/CompressedImage"](header=self.header(t_ns, frame), format=fmt,
                                                         data=np.frombuffer(data, dtype=np.uint8))

    def camera_info(self, t_ns, frame, K, w, h, D=None, binning: int = 0, offset=(0, 0)):
        """A CameraInfo of images w × h with intrinsics K; with ``binning`` > 1 or an ``offset``, written as a
        driver does for binned images of a region of the full sensor (K, size and region at full resolution)."""
        x0, y0 = offset
        b = max(1, binning)
        roi = self.T["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
        if b > 1 or offset != (0, 0):
            K = np.array([[b * K[0, 0], b * K[0, 1], b * K[0, 2] + x0], [0.0, b * K[1, 1], b * K[1, 2] + y0],
                          [0.0, 0.0, 1.0]])
            roi = self.T["sensor_msgs/msg/RegionOfInterest"](x_offset=x0, y_offset=y0, height=b * h, width=b * w,
                                                             do_rectify=False)
            w, h = b * w + 2 * x0, b * h + 2 * y0  # the whole sensor, larger than the region
        names = ("D", "K", "R", "P") if self.ros == 1 else ("d", "k", "r", "p")
        P = np.hstack([K, np.zeros((3, 1))]).reshape(-1)
        values = (np.zeros(5) if D is None else np.asarray(D, float), np.asarray(K, float).reshape(-1),
                  np.eye(3).reshape(-1), P)
        return self.T["sensor_msgs/msg/CameraInfo"](header=self.header(t_ns, frame), height=h, width=w,
                                                    distortion_model="plumb_bob", binning_x=binning, binning_y=binning,
                                                    roi=roi,
                                                    **dict(zip(names, values, strict=True)))

    def _vq(self, T):
        qx, qy, qz, qw = Rotation.from_matrix(T[:3, :3]).as_quat()
        return T[:3, 3], self.T["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw)

    def pose(self, T):
        p, q = self._vq(T)
        return self.T["geometry_msgs/msg/Pose"](position=self.T["geometry_msgs/msg/Point"](x=p[0], y=p[1], z=p[2]),
                                                orientation=q)

    def odometry(self, t_ns, T):
        cov = np.zeros(36)
        pose = self.T["geometry_msgs/msg/PoseWithCovariance"](pose=self.pose(T), covariance=cov)
        zero = self.T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        twist = self.T["geometry_msgs/msg/TwistWithCovariance"](
            twist=self.T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=cov)
        return self.T["nav_msgs/msg/Odometry"](header=self.header(t_ns, "odom"), child_frame_id="base_link",
                                               pose=pose, twist=twist)

    def pose_stamped(self, t_ns, T):
        return self.T["geometry_msgs/msg/PoseStamped"](header=self.header(t_ns, "map"), pose=self.pose(T))

    def tf(self, t_ns, edges):
        out = []
        for parent, child, T in edges:
            p, q = self._vq(T)
            transform = self.T["geometry_msgs/msg/Transform"](
                translation=self.T["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]), rotation=q)
            out.append(self.T["geometry_msgs/msg/TransformStamped"](header=self.header(t_ns, parent),
                                                                    child_frame_id=child, transform=transform))
        return self.T["tf2_msgs/msg/TFMessage"](transforms=out)


def write_bag(mcap_path, bag_path, ros: int = 2, storage: str = "sqlite3", ground_truth: bool = True,
              compressed: bool = False, depth_mm: bool = False, max_frames: int | None = None,
              times_s=None, depth_filter=None, truth_type: str = "PoseStamped",
              depth_offset_s: float = 0.0, depth_camera: tuple | None = None, distortion=None,
              colour_encoding: str = "bgr8", compression: str | None = None, rename: dict | None = None,
              infrared: bool = False, tf_static: bool = True, binning: int = 0, roi_offset=(0, 0)) -> Path:
    """Write the frames of ``mcap_path`` as a bag at ``bag_path`` (a ``.bag`` file for ROS 1, a folder for ROS 2).

    ``times_s`` replaces the header stamps (s; the bag's receive times stay the frames' times);
    ``depth_filter(depth) -> depth`` alters the depth images (both to make bad bags). ``truth_type``:
    the ground truth's message (PoseStamped, TransformStamped or Odometry); ``depth_offset_s`` shifts
    the depth images' stamps. ``depth_camera`` = (K (3, 3), (width, height), T_color_depth (4, 4)): a
    depth camera of its own (not aligned to colour), its images made from the recording's depth with
    :func:`stslam.io.depth_registration.register_depth` and published as a RealSense does, on
    ``/camera/depth/image_rect_raw`` with ``/camera/depth/camera_info`` and its optical frame on /tf_static.
    ``distortion`` (5 plumb_bob coefficients): the colour camera's lens distortion, put into the colour
    and aligned depth images (:func:`distort_image`) and into its CameraInfo. ``colour_encoding``: raw colour
    as ``bgr8`` (a RealSense) or ``bgra8`` (an Azure Kinect, alpha 255). ``compression`` (ROS 2): ``"file"`` or
    ``"message"``, the bag compressed with zstd as ``ros2 bag record --compression-mode`` does. ``rename``
    maps default topic names to the bag's; ``infrared`` adds a RealSense's left infrared stream
    (``/camera/infra1/image_rect_raw``, mono8, the colour image's grey) in the depth camera's frame;
    ``tf_static=False`` leaves the mount out (a bag recorded without TF). ``binning`` and ``roi_offset``:
    the colour CameraInfo describes the images as binned from a region of a larger sensor (REP 104).
    """
    from rosbags.typesys import Stores, get_typestore

    bag_path = Path(bag_path)
    typestore = get_typestore(Stores.ROS1_NOETIC if ros == 1 else Stores.ROS2_HUMBLE)
    if "tf2_msgs/msg/TFMessage" not in typestore.types:  # the ROS 1 store lacks it
        from rosbags.typesys import get_types_from_msg
        typestore.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"))
    m = _Messages(typestore, ros)
    if ros == 1:
        from rosbags.rosbag1 import Writer
        writer = Writer(bag_path)
        serialize = typestore.serialize_ros1
    else:
        from rosbags.rosbag2 import StoragePlugin, Writer
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer(bag_path, version=9, storage_plugin=plugin)
        if compression is not None:
            from rosbags.rosbag2 import CompressionFormat, CompressionMode
            writer.set_compression(CompressionMode[compression.upper()], CompressionFormat.ZSTD)
        serialize = typestore.serialize_cdr
    image_type = "sensor_msgs/msg/CompressedImage" if compressed else "sensor_msgs/msg/Image"
    kinds = {"/camera/color/image_raw": image_type, "/camera/aligned_depth_to_color/image_raw": image_type,
             "/camera/color/camera_info": "sensor_msgs/msg/CameraInfo", "/odom": "nav_msgs/msg/Odometry",
             "/tf_static": "tf2_msgs/msg/TFMessage"}
    depth_topic = "/camera/aligned_depth_to_color/image_raw"
    depth_frame = OPTICAL_FRAME
    if depth_camera is not None:
        depth_topic, depth_frame = "/camera/depth/image_rect_raw", DEPTH_FRAME
        kinds[depth_topic] = kinds.pop("/camera/aligned_depth_to_color/image_raw")
        kinds["/camera/depth/camera_info"] = "sensor_msgs/msg/CameraInfo"
    if ground_truth:
        kinds["/mocap/base"] = {"PoseStamped": "geometry_msgs/msg/PoseStamped", "Odometry": "nav_msgs/msg/Odometry",
                                "TransformStamped": "geometry_msgs/msg/TransformStamped"}[truth_type]
    with writer:
        if infrared:
            kinds["/camera/infra1/image_rect_raw"] = "sensor_msgs/msg/Image"
        if not tf_static:
            del kinds["/tf_static"]
        rename = rename or {}
        conns = {topic: writer.add_connection(rename.get(topic, topic), kind, typestore=typestore)
                 for topic, kind in kinds.items()}

        def put(topic, msg, _):
            writer.write(conns[topic], received_ns, serialize(msg, kinds[topic]))

        for k, frame in enumerate(RGBDMcapReader(mcap_path)):
            if max_frames is not None and k >= max_frames:
                break
            received_ns = int(round(frame.t_s * 1e9))
            t_ns = int(round((frame.t_s if times_s is None else times_s[k]) * 1e9))
            if k == 0:
                # The mount split in two, as a RealSense driver publishes it.
                T_link = np.eye(4)
                T_link[:3, 3] = frame.T_base_camera[:3, 3]
                T_optical = np.linalg.inv(T_link) @ frame.T_base_camera
                edges = [("base_link", LINK_FRAME, T_link), (LINK_FRAME, OPTICAL_FRAME, T_optical)]
                if depth_camera is not None:
                    edges.append((LINK_FRAME, DEPTH_FRAME, T_optical @ depth_camera[2]))
                if tf_static:
                    put("/tf_static", m.tf(t_ns, edges), t_ns)
            h, w = frame.rgb.shape[:2]
            put("/camera/color/camera_info", m.camera_info(t_ns, OPTICAL_FRAME, frame.K, w, h, distortion, binning,
                                                                     tuple(roi_offset)), t_ns)
            depth = frame.depth_m if depth_filter is None else depth_filter(frame.depth_m)
            colour = frame.rgb
            if distortion is not None:
                colour = distort_image(frame.rgb, frame.K, distortion)
                depth = distort_image(depth.astype(np.float32), frame.K, distortion, nearest=True)
            if depth_camera is not None:
                K_d, size_d, T_color_depth = depth_camera
                depth = register_depth(depth, frame.K, K_d, np.linalg.inv(T_color_depth), size_d)
                put("/camera/depth/camera_info", m.camera_info(t_ns, DEPTH_FRAME, K_d, *size_d), t_ns)
            if compressed:
                ok, jpeg = cv2.imencode(".jpg", colour[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, 95])
                mm = np.where(np.isfinite(depth), np.rint(depth * 1000.0), 0).astype(np.uint16)
                ok2, png = cv2.imencode(".png", mm)
                assert ok and ok2
                rgb_msg = m.compressed(t_ns, OPTICAL_FRAME, jpeg.tobytes(), "bgr8; jpeg compressed bgr8")
                depth_msg = m.compressed(t_ns, depth_frame, b"\0" * 12 + png.tobytes(),
                                         "16UC1; compressedDepth png")
            else:
                bgr = colour[..., ::-1]
                if colour_encoding == "bgra8":
                    bgr = np.dstack([bgr, np.full(bgr.shape[:2], 255, np.uint8)])
                rgb_msg = m.image(t_ns, OPTICAL_FRAME, bgr, colour_encoding)
                if depth_mm:
                    mm = np.where(np.isfinite(depth), np.rint(depth * 1000.0), 0).astype("<u2")
                    depth_msg = m.image(t_ns, depth_frame, mm, "16UC1")
                else:
                    depth_msg = m.image(t_ns + int(round(depth_offset_s * 1e9)), depth_frame,
                                        depth.astype("<f4"), "32FC1")
            put("/camera/color/image_raw", rgb_msg, t_ns)
            if infrared:
                grey = cv2.cvtColor(np.ascontiguousarray(frame.rgb), cv2.COLOR_RGB2GRAY)
                put("/camera/infra1/image_rect_raw", m.image(t_ns, DEPTH_FRAME, grey, "mono8"), t_ns)
            put(depth_topic, depth_msg, t_ns)
            put("/odom", m.odometry(t_ns, frame.T_world_base_odom), t_ns)
            if ground_truth:
                if truth_type == "PoseStamped":
                    truth = m.pose_stamped(t_ns, frame.T_world_base)
                elif truth_type == "Odometry":
                    truth = m.odometry(t_ns, frame.T_world_base)
                else:
                    truth = m.tf(t_ns, [("map", "base_link", frame.T_world_base)]).transforms[0]
                put("/mocap/base", truth, t_ns)
    return bag_path
