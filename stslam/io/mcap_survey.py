"""What a Foxglove (protobuf) MCAP recording holds, and the ``mcap_topics.*`` that run it (SPEC 9, 15).

The MCAP counterpart of :mod:`stslam.io.bag_survey`, for ``+exp=fridge
mcap=<file>``: every topic with its schema, count, rate, frame and image
encoding, and the SPEC 9 roles chosen by content:

* colour and depth: ``foxglove.RawImage``/``CompressedImage`` by encoding or
  format (:func:`stslam.io.bag_survey.image_kind`), infrared and grey ranked
  below colour;
* calibration: the ``foxglove.CameraCalibration`` in the colour frame (else the first);
* the pose topics (``FrameTransform``, ``FrameTransforms``, ``PoseInFrame``), by
  the frames of their first messages: the door is the topic with two frames, one
  the parent of the other; the mount and the true camera pose end in the colour
  frame (the mount is the one with the fewest messages); odometry is the one
  whose name or child frame says ``odom``; the true base pose, one whose name
  says motion capture or ground truth, else the one left.

Roles the fridge experiment needs and that are missing are named in ``notes``.
"""

from __future__ import annotations

from pathlib import Path

from mcap.reader import make_reader
from mcap_protobuf.decoder import DecoderFactory

from stslam.errors import InputFileError
from stslam.io import mcap_topics as mt
from stslam.io import rosbag_read as rb
from stslam.io.bag_survey import GROUND_TRUTH_WORDS, BagSurvey, TopicSummary, colour_rank, image_kind, survey_bag
from stslam.io.mcap_errors import LIBRARY_ERRORS, begins_as_mcap, reading
from stslam.io.mcap_side import pose_parts

POSE_SCHEMAS = (mt.SCHEMA_FRAME_TRANSFORM, mt.SCHEMA_FRAME_TRANSFORMS, mt.SCHEMA_POSE_IN_FRAME)
FIRST_MESSAGES = 4  # per pose topic, enough to see both door frames when they come one per message


def _frames_of(schema: str, topic: str, decoded) -> list[tuple[str, str]]:
    """(parent, child) of each pose in a message, named as the reader names them (:func:`mcap_side.pose_parts`)."""
    return [(parent, child) for _, parent, child, _, _ in pose_parts(schema, topic, decoded)]


def survey_recording(path) -> BagSurvey:
    """:func:`survey_mcap` for an MCAP of protobuf messages, :func:`stslam.io.bag_survey.survey_bag` for a ROS
    bag (a ROS 1 file, a ROS 2 folder, or a ROS 2 bag's own MCAP of cdr messages)."""
    if Path(path).is_file() and begins_as_mcap(path):
        with open(path, "rb") as handle:
            try:
                summary = make_reader(handle).get_summary()
            except LIBRARY_ERRORS:
                summary = None
        if summary is not None and any(c.message_encoding == "protobuf" for c in summary.channels.values()):
            return survey_mcap(path)
    return survey_bag(path)


def survey_mcap(path) -> BagSurvey:
    """Topics of the MCAP at ``path`` and the ``mcap_topics.*`` settings that fit them (module docstring)."""
    path = str(path)
    with open(path, "rb") as handle, reading(path):
        try:
            reader = make_reader(handle, decoder_factories=[DecoderFactory()])
            summary = reader.get_summary()
        except LIBRARY_ERRORS as error:
            raise InputFileError(path, f"not a readable MCAP file ({type(error).__name__}: {error})") from None
        if summary is None or summary.statistics is None:
            raise InputFileError(path, "MCAP without a summary and statistics (salvage it first: python "
                                       f"experiments/salvage_mcap.py {path} <new.mcap>)")
        stats = summary.statistics
        duration = max((stats.message_end_time - stats.message_start_time) * 1e-9, 1e-9)
        topics, firsts = [], {}
        for channel in sorted(summary.channels.values(), key=lambda c: c.topic):
            schema = summary.schemas.get(channel.schema_id)
            name = schema.name if schema is not None else "no schema"
            count = int(stats.channel_message_counts.get(channel.id, 0))
            decoded = []
            if channel.message_encoding == "protobuf" and count:
                limit = FIRST_MESSAGES if name in POSE_SCHEMAS else 1
                for _, _, _, message in reader.iter_decoded_messages(topics=[channel.topic]):
                    decoded.append(message)
                    if len(decoded) >= limit:
                        break
            firsts[channel.topic] = (name, decoded)
            topics.append(TopicSummary(channel.topic, name, count, (count - 1) / duration if count > 1 else 0.0,
                                       *_frame_and_detail(name, channel.topic, decoded)))
    defaults = {f"mcap_topics.{k}": v for k, v in vars(mt.DEFAULT_TOPICS).items()}
    survey = BagSurvey(path, duration, topics, defaults=defaults, runner="fridge")
    _choose(survey, firsts)
    return survey


def _frame_and_detail(schema: str, topic: str, decoded: list) -> tuple[str, str]:
    if not decoded:
        return "", ""
    first = decoded[0]
    if schema == mt.SCHEMA_RAW_IMAGE:
        return first.frame_id, f"{first.encoding} {first.width}×{first.height}"
    if schema == mt.SCHEMA_COMPRESSED_IMAGE:
        return first.frame_id, f"format {first.format!r}"
    if schema == mt.SCHEMA_CAMERA_CALIBRATION:
        return first.frame_id, f"{first.width}×{first.height}"
    if schema in POSE_SCHEMAS:
        pairs = sorted({p for m in decoded for p in _frames_of(schema, topic, m)})
        return "", ", ".join(f"{parent} → {child}" for parent, child in pairs)
    return "", ""


def _choose(survey: BagSurvey, firsts: dict) -> None:
    s, notes = survey.settings, survey.notes
    rows = {t.topic: t for t in survey.topics}
    colours, depths = [], []
    for topic, (schema, decoded) in firsts.items():
        if schema not in (mt.SCHEMA_RAW_IMAGE, mt.SCHEMA_COMPRESSED_IMAGE) or not decoded:
            continue
        raw = schema == mt.SCHEMA_RAW_IMAGE
        encoding = decoded[0].encoding if raw else decoded[0].format
        kind = image_kind(rb.IMAGE if raw else rb.COMPRESSED, encoding, topic)
        if kind == "colour":
            colours.append((colour_rank(rows[topic], encoding), rows[topic]))
        elif kind == "depth":
            depths.append(rows[topic])
    colour = max(colours, key=lambda x: x[0])[1] if colours else None
    camera = colour.frame if colour is not None else None
    depth = max(depths, key=lambda d: (d.frame == camera, d.count)) if depths else None  # aligned first
    for role, what, found in (("rgb", "colour", colour), ("depth", "depth", depth)):
        if found is None:
            notes.append(f"cannot run: no {what} image topic")
        else:
            s[f"mcap_topics.{role}"] = found.topic
    calibrations = [t for t in survey.topics if t.msgtype == mt.SCHEMA_CAMERA_CALIBRATION]
    if calibrations:
        s["mcap_topics.calibration"] = max(calibrations, key=lambda t: (t.frame == camera, t.count)).topic
    else:
        notes.append("cannot run: no foxglove.CameraCalibration topic")
    _choose_poses(survey, firsts, camera)


def _choose_poses(survey: BagSurvey, firsts: dict, camera: str | None) -> None:
    s, notes = survey.settings, survey.notes
    counts = {t.topic: t.count for t in survey.topics}
    left = {topic: {p for m in decoded for p in _frames_of(schema, topic, m)}  # pose topics not yet given a role
            for topic, (schema, decoded) in firsts.items() if schema in POSE_SCHEMAS and decoded}
    door = next((t for t, pairs in left.items() if len(pairs) == 2
                 and {c for _, c in pairs} & {p for p, _ in pairs}), None)
    if door is not None:
        s["mcap_topics.door"] = door
        del left[door]
    at_camera = sorted((t for t, pairs in left.items() if any(c == camera for _, c in pairs)),
                       key=counts.__getitem__)
    if at_camera:
        s["mcap_topics.camera_mount"] = at_camera[0]
        if len(at_camera) > 1:
            s["mcap_topics.ground_truth_camera"] = at_camera[1]
        for t in at_camera[:2]:
            del left[t]
    else:
        notes.append(f"cannot run: no pose topic ends in the colour frame {camera} (the camera mount)")
    odometry = next((t for t, pairs in left.items()
                     if "odom" in t.lower() or any("odom" in c.lower() for _, c in pairs)), None)
    if odometry is None:
        notes.append("cannot run: no odometry pose topic (a name or child frame with 'odom')")
    else:
        s["mcap_topics.odometry"] = odometry
        del left[odometry]
    truth = next((t for t in left if GROUND_TRUTH_WORDS.search(t)), None) or (next(iter(left)) if len(left) == 1
                                                                               else None)
    if truth is not None:
        s["mcap_topics.ground_truth_base"] = truth
        del left[truth]
    if left:
        notes.append(f"pose topics not used: {', '.join(sorted(left))}")
