"""Topics, frames and encodings of an RGB-D MCAP recording (SPEC 9): the one place they are defined.

Every message is protobuf with a Foxglove schema (package
``foxglove_schemas_protobuf``). Times are the message's ``timestamp`` field
(the MCAP log time is used when it is unset); the generated sequence writes
log time = publish time = timestamp = k / rate_hz for frame k.

Topics (:class:`RGBDTopics` holds the names; a user's recording may rename them)

==========================  ===========================  ======================================================
topic                       schema                       content
==========================  ===========================  ======================================================
``/camera/rgb/image``       ``foxglove.RawImage``        colour image, ``rgb8`` as written (read: every colour
                                                         encoding of :mod:`stslam.io.pixels`, e.g. ``bgra8``,
                                                         Bayer, ``uyvy``; or a ``foxglove.CompressedImage``,
                                                         JPEG or PNG); frame ``camera_optical``. Required.
``/camera/depth/image``     ``foxglove.RawImage``        depth along the optical axis, registered to the colour
                                                         image (same size and intrinsics): ``32FC1`` metres with
                                                         NaN where the sensor has no return (0 and ±inf are read
                                                         as no return too), or ``16UC1``/``mono16`` millimetres
                                                         with 0 for no return; or a
                                                         ``foxglove.CompressedImage``, a 16-bit PNG in mm.
                                                         Required.
``/camera/calibration``     ``foxglove.CameraCalibration``  K (row-major 3 × 3, pixels), ``plumb_bob`` with zero
                                                         distortion as written (the images are rectified; a
                                                         file with ``plumb_bob`` or ``rational_polynomial``
                                                         coefficients is undistorted on reading),
                                                         P = [K | 0], width and height of the images. Required.
``/ground_truth/base``      ``foxglove.FrameTransform``  ``world`` → ``base_link``: true robot pose.
``/robot/camera_mount``     ``foxglove.FrameTransform``  ``base_link`` → ``camera_optical``: the fixed camera
                                                         mount (written once, at the first frame).
``/ground_truth/camera``    ``foxglove.FrameTransform``  ``world`` → ``camera_optical``: true camera pose, for
                                                         recordings that track the camera directly (not
                                                         written by the generator: there it is
                                                         ground truth base ∘ camera mount).
``/odometry/base``          ``foxglove.FrameTransform``  ``world`` → ``base_link_odom``: robot pose integrated
                                                         from the noisy odometry controls (SPEC 5.1), starting
                                                         at the true first pose.
``/door/ground_truth``      ``foxglove.FrameTransform``  two transforms per frame, see below.
==========================  ===========================  ======================================================

Only the three camera topics are required; each of the others, when
present, fills its field of :class:`stslam.io.mcap_read.RGBDFrame`. The pose
topics are read as written by other tools too: a ``foxglove.FrameTransforms``
(each transform in it counts as a FrameTransform of its own time stamp) or, but
for the door, a ``foxglove.PoseInFrame`` (the pose in ``frame_id`` of the body
the topic names).

Frames: ``world`` (z up, floor z = 0, metres); ``base_link`` (robot: x forward,
y left, z up, on the floor); ``base_link_odom`` (the same body where odometry
believes it is); ``camera_optical`` (x right, y down, z forward, see
:mod:`stslam.robot.pinhole`); ``door_hinge`` and ``door_panel``. A FrameTransform
parent → child gives the pose of the child in the parent: X_parent = R X_child + t.

Door ground truth (topic ``/door/ground_truth``), two FrameTransforms at each
time stamp:

* ``world`` → ``door_hinge``: translation = a point on the hinge axis (the
  generator uses floor height); rotation = the hinge frame, whose +z axis is
  the hinge axis direction and whose +x axis points from the hinge along the
  *closed* door panel towards its free edge.
* ``door_hinge`` → ``door_panel``: zero translation and a rotation about the
  hinge z axis by the door angle φ, i.e. quaternion (0, 0, sin φ/2, cos φ/2):
  φ = 2 atan2(q_z, q_w) (q_x, q_y are ignored), 0 = closed, φ > 0 turns the
  panel by the right-hand rule about the axis (opening).

So axis point = hinge translation, axis direction = third column of the
hinge rotation, angle = φ; the door frame tree shows the door in Foxglove's 3D
panel.

A metadata record named ``stslam.rgbd.sequence`` holds the generator's
parameters (seed, rate, noise model, α) as strings.
"""

from __future__ import annotations

from dataclasses import dataclass

WORLD_FRAME = "world"
BASE_FRAME = "base_link"
ODOM_BASE_FRAME = "base_link_odom"
CAMERA_FRAME = "camera_optical"
DOOR_HINGE_FRAME = "door_hinge"
DOOR_PANEL_FRAME = "door_panel"

SCHEMA_RAW_IMAGE = "foxglove.RawImage"
SCHEMA_COMPRESSED_IMAGE = "foxglove.CompressedImage"
SCHEMA_CAMERA_CALIBRATION = "foxglove.CameraCalibration"
SCHEMA_FRAME_TRANSFORM = "foxglove.FrameTransform"
SCHEMA_FRAME_TRANSFORMS = "foxglove.FrameTransforms"
SCHEMA_POSE_IN_FRAME = "foxglove.PoseInFrame"

DEPTH_WRITE_ENCODINGS = ("32FC1", "16UC1")

METADATA_NAME = "stslam.rgbd.sequence"


@dataclass(frozen=True)
class RGBDTopics:
    """Topic names of an RGB-D recording (defaults: the generated fridge sequence)."""

    rgb: str = "/camera/rgb/image"
    depth: str = "/camera/depth/image"
    calibration: str = "/camera/calibration"
    ground_truth_base: str = "/ground_truth/base"
    ground_truth_camera: str = "/ground_truth/camera"
    odometry: str = "/odometry/base"
    camera_mount: str = "/robot/camera_mount"
    door: str = "/door/ground_truth"

    def required(self) -> tuple[str, ...]:
        """Topics a recording must have."""
        return (self.rgb, self.depth, self.calibration)

    def schema_of(self) -> dict[str, tuple[str, ...]]:
        """Schema names accepted per topic."""
        image = (SCHEMA_RAW_IMAGE, SCHEMA_COMPRESSED_IMAGE)
        schemas = {self.rgb: image, self.depth: image, self.calibration: (SCHEMA_CAMERA_CALIBRATION,)}
        for topic in (self.ground_truth_base, self.ground_truth_camera, self.odometry, self.camera_mount):
            schemas[topic] = (SCHEMA_FRAME_TRANSFORM, SCHEMA_FRAME_TRANSFORMS, SCHEMA_POSE_IN_FRAME)
        schemas[self.door] = (SCHEMA_FRAME_TRANSFORM, SCHEMA_FRAME_TRANSFORMS)  # two named frames
        return schemas


DEFAULT_TOPICS = RGBDTopics()
