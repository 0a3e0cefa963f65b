"""Test helper: an MCAP recording copied under other topic names, as another tool would log the same content."""

from __future__ import annotations

from mcap.reader import make_reader
from mcap.writer import Writer

# SPEC 9 name → another name, and the mcap_topics key of each.
RENAMED = {"/camera/rgb/image": "/cam/color", "/camera/depth/image": "/cam/depth", "/camera/calibration":
           "/cam/info", "/ground_truth/base": "/vicon/base", "/odometry/base": "/wheels", "/robot/camera_mount":
           "/mount", "/door/ground_truth": "/vicon/door"}
RENAMED_KEYS = {"/camera/rgb/image": "rgb", "/camera/depth/image": "depth", "/camera/calibration": "calibration",
                "/ground_truth/base": "ground_truth_base", "/odometry/base": "odometry",
                "/robot/camera_mount": "camera_mount", "/door/ground_truth": "door"}


def renamed_copy(source, target):
    """The MCAP ``source`` with its topics renamed by RENAMED: the same schemas, messages and times."""
    with open(source, "rb") as read_handle, open(target, "wb") as write_handle:
        reader = make_reader(read_handle)
        writer = Writer(write_handle)
        writer.start()
        schemas, channels = {}, {}
        for schema, channel, message in reader.iter_messages(log_time_order=True):
            if schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(RENAMED.get(channel.topic, channel.topic),
                                                               channel.message_encoding, schemas[schema.id])
            writer.add_message(channels[channel.id], message.log_time, message.data, message.publish_time)
        writer.finish()
    return target
