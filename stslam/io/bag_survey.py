"""What a ROS bag holds, and the ``convert.py`` settings that would read it (SPEC 15).

A recording from somebody else's robot rarely uses the default topic names of
``conf/convert.yaml``. :func:`survey_bag` lists every topic with its message
type, count, rate, frame and image encoding, and picks the topics a conversion
needs by what they carry, not by their names alone:

* colour: an ``Image`` with a colour encoding (:mod:`stslam.io.pixels`) or a
  ``CompressedImage`` that is not depth; infrared streams (``infra``/``ir`` in
  the name) and grey images rank below colour ones;
* depth: an ``Image`` in a depth encoding or a ``compressedDepth`` image (a
  PNG image with ``depth`` in its name too); depth aligned to colour (same
  frame as the colour images, or ``aligned`` in the name) first; otherwise the
  depth camera's own ``CameraInfo`` (same frame) becomes ``topics.depth_info``;
* the colour ``CameraInfo``: the one in the colour images' frame, else the one
  beside the image topic;
* odometry: a ``nav_msgs/Odometry`` whose name does not say motion capture or
  ground truth; its ``child_frame_id`` is the robot's base frame;
* ground truth: a ``PoseStamped``/``TransformStamped``, or an ``Odometry`` whose
  name says motion capture or ground truth;
* the mount: ``/tf_static``, or ``/tf`` when the bag has no ``/tf_static``.

What it cannot find is said in ``notes``; the suggested command names only the
settings that differ from the defaults.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass, field

from stslam.io import pixels
from stslam.io import rosbag_read as rb
from stslam.io.bag_convert import BagTopics

GROUND_TRUTH_WORDS = re.compile(r"mocap|vicon|optitrack|qualisys|ground_?truth|(^|[/_])gt($|[/_])", re.IGNORECASE)
INFRARED_WORDS = re.compile(r"infra|(^|[/_])ir($|[/_\d])", re.IGNORECASE)
DEFAULT_BASE_FRAME = "base_link"


@dataclass(frozen=True)
class TopicSummary:
    """One topic of a bag: message type, count, mean rate (Hz), the first message's frame and image details."""

    topic: str
    msgtype: str
    count: int
    rate_hz: float
    frame: str = ""
    detail: str = ""


def convert_defaults() -> dict[str, str | None]:
    """``conf/convert.yaml``'s topic and frame settings, by override key."""
    return {f"topics.{k}": v for k, v in vars(BagTopics()).items()} | {"frames.base": DEFAULT_BASE_FRAME}


@dataclass
class BagSurvey:
    """A recording's topics and the settings chosen for it: a bag's for ``convert.py`` (keys of
    ``conf/convert.yaml``), or an MCAP's for ``+exp=fridge mcap=`` (``runner="fridge"``, ``mcap_topics.*``)."""

    path: str
    duration_s: float
    topics: list[TopicSummary]
    settings: dict[str, str | None] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    defaults: dict[str, str | None] = field(default_factory=convert_defaults)
    runner: str = "convert"

    def overrides(self) -> list[str]:
        """The chosen settings that differ from the defaults, as Hydra overrides."""
        return [f"{key}={'null' if value is None else value}" for key, value in self.settings.items()
                if self.defaults.get(key, "…") != value]

    def command(self, out: str = "data/rec.mcap") -> str:
        if self.runner == "fridge":
            words = ["python", "experiments/run.py", "+exp=fridge", f"mcap={self.path}", *self.overrides()]
        else:
            words = ["python", "experiments/convert.py", f"bag={self.path}", f"out={out}", *self.overrides()]
        return " ".join(shlex.quote(w) for w in words)

    def lines(self, out: str = "data/rec.mcap") -> list[str]:
        width = max([len(t.topic) for t in self.topics] + [5])
        rows = [f"{self.path}: {len(self.topics)} topics over {self.duration_s:.1f} s",
                f"  {'topic':<{width}}  {'type':<34} {'count':>7} {'Hz':>7}  frame / details"]
        for t in self.topics:
            extra = " ".join(x for x in (t.frame, t.detail) if x)
            rows.append(f"  {t.topic:<{width}}  {t.msgtype:<34} {t.count:>7} {t.rate_hz:>7.1f}  {extra}")
        rows += [f"note: {n}" for n in self.notes]
        ready = not any(n.startswith("cannot ") for n in self.notes)
        rows.append(("run with:" if self.runner == "fridge" else "convert with:") if ready
                    else "closest command (fix the notes first):")
        rows.append(f"  {self.command(out)}")
        return rows


def image_kind(msgtype: str, encoding: str, topic: str) -> str | None:
    """``"colour"``, ``"depth"`` or None (unreadable) for an image message's encoding or format."""
    if msgtype == rb.COMPRESSED:
        fmt = encoding.lower()
        if "compresseddepth" in fmt or ("depth" in topic.lower() and "png" in fmt):
            return "depth"
        return "colour"
    if encoding in pixels.DEPTH_ENCODINGS:
        return "depth"
    return "colour" if encoding in pixels.COLOUR_ENCODINGS else None


def colour_rank(summary: TopicSummary, encoding: str) -> tuple:
    """Sort key of a colour image topic: not infrared, named colour or rgb, not grey, more messages."""
    name = summary.topic.lower()
    return (INFRARED_WORDS.search(name) is None, "color" in name or "rgb" in name,
            encoding not in ("mono8", "8UC1"), summary.count)


def _first(reader, path, connection):
    for _, _, msg, _ in rb.messages(reader, path, [connection]):
        return msg
    return None


def _camera_info_of(infos: list[TopicSummary], image: TopicSummary) -> TopicSummary | None:
    """The CameraInfo in the image's frame, else the one beside the image topic (``…/camera_info``)."""
    beside = image.topic.rsplit("/", 1)[0] + "/camera_info"
    return next((i for i in infos if i.frame and i.frame == image.frame), None) or \
        next((i for i in infos if i.topic == beside), None)


def _take_camera_info(infos: list[TopicSummary], image: TopicSummary, settings: dict, key: str, notes: list,
                      missing: str) -> TopicSummary | None:
    """The image's CameraInfo (:func:`_camera_info_of`), its topic put in ``settings[key]``; None, and the
    note ``cannot convert: <missing>``, when there is none."""
    info = _camera_info_of(infos, image)
    if info is None:
        notes.append(f"cannot convert: {missing}")
    else:
        settings[key] = info.topic
    return info


def survey_bag(path) -> BagSurvey:
    """Topics of the bag at ``path`` and the convert settings that fit them (module docstring)."""
    with rb.open_bag(path) as reader:
        duration = max(reader.duration * 1e-9, 1e-9) if reader.connections else 0.0
        firsts, summaries = {}, []
        for c in sorted(reader.connections, key=lambda c: c.topic):
            msg = _first(reader, path, c) if c.msgcount else None
            firsts[c.topic] = msg
            frame = getattr(getattr(msg, "header", None), "frame_id", "") or ""
            detail = ""
            if c.msgtype == rb.IMAGE and msg is not None:
                detail = f"{msg.encoding} {msg.width}×{msg.height}"
            elif c.msgtype == rb.COMPRESSED and msg is not None:
                detail = f"format {msg.format!r}"
            elif c.msgtype == rb.CAMERA_INFO and msg is not None:
                detail = f"{msg.width}×{msg.height} {msg.distortion_model}"
            elif c.msgtype == rb.ODOMETRY and msg is not None:
                detail = f"child {msg.child_frame_id}"
            rate = (c.msgcount - 1) / duration if duration and c.msgcount > 1 else 0.0  # intervals per second
            summaries.append(TopicSummary(c.topic, c.msgtype, int(c.msgcount), rate, frame.lstrip("/"), detail))
        survey = BagSurvey(str(path), duration, summaries)
        _choose(survey, firsts)
    return survey


def _choose(survey: BagSurvey, firsts: dict) -> None:
    by_type: dict[str, list[TopicSummary]] = {}
    for t in survey.topics:
        by_type.setdefault(t.msgtype, []).append(t)
    s, notes = survey.settings, survey.notes
    colours, depths = [], []
    for t in by_type.get(rb.IMAGE, []) + by_type.get(rb.COMPRESSED, []):
        msg = firsts[t.topic]
        if msg is None:
            continue
        encoding = str(msg.format if t.msgtype == rb.COMPRESSED else msg.encoding)
        kind = image_kind(t.msgtype, encoding, t.topic)
        if kind == "colour":
            colours.append((colour_rank(t, encoding), t))
        elif kind == "depth":
            depths.append(t)
    if not colours:
        notes.append("cannot convert: no colour image topic (sensor_msgs/Image in a colour encoding or "
                     "CompressedImage)")
        return
    colours.sort(key=lambda x: x[0], reverse=True)
    colour = colours[0][1]
    s["topics.rgb"] = colour.topic
    others = [t.topic for rank, t in colours[1:] if rank[:2] == colours[0][0][:2]]  # named as colour too
    if others:
        notes.append(f"colour taken from {colour.topic}; other colour cameras: {', '.join(others)}")
    infos = by_type.get(rb.CAMERA_INFO, [])
    _take_camera_info(infos, colour, s, "topics.camera_info", notes,
                      f"no sensor_msgs/CameraInfo in frame {colour.frame or '?'} or beside {colour.topic}")
    if not depths:
        notes.append("cannot convert: no depth image topic (16UC1, 32FC1 or compressedDepth)")
    else:
        depth = max(depths, key=lambda d: (INFRARED_WORDS.search(d.topic) is None, d.frame == colour.frame,
                                           "align" in d.topic.lower(), d.count))
        s["topics.depth"] = depth.topic
        aligned = depth.frame == colour.frame or "align" in depth.topic.lower()
        s["topics.depth_info"] = None
        if not aligned:
            own = _take_camera_info(infos, depth, s, "topics.depth_info", notes,
                                    f"{depth.topic} is in frame {depth.frame}, not the colour frame, and no "
                                    f"CameraInfo in that frame was found for re-projecting it")
            if own is not None:
                notes.append(f"{depth.topic} is the depth camera's own image: it is re-projected into the colour "
                             f"camera with {own.topic} and the TF between the two frames")
    odometry = [t for t in by_type.get(rb.ODOMETRY, []) if not GROUND_TRUTH_WORDS.search(t.topic)]
    if not odometry:
        notes.append("cannot convert: no nav_msgs/Odometry topic (the filters take their controls from odometry)")
    else:
        odom = max(odometry, key=lambda t: ("odom" in t.topic.lower(), t.count))
        s["topics.odometry"] = odom.topic
        child = str(firsts[odom.topic].child_frame_id).lstrip("/") if firsts[odom.topic] is not None else ""
        if child:
            s["frames.base"] = child
    truths = [t for t in by_type.get(rb.POSE_STAMPED, []) + by_type.get(rb.TRANSFORM_STAMPED, [])
              + by_type.get(rb.ODOMETRY, []) if t.msgtype != rb.ODOMETRY or GROUND_TRUTH_WORDS.search(t.topic)]
    truths.sort(key=lambda t: (GROUND_TRUTH_WORDS.search(t.topic) is None, -t.count))
    s["topics.ground_truth"] = truths[0].topic if truths else None
    if len(truths) > 1:
        notes.append(f"ground truth taken from {truths[0].topic}; other candidates: "
                     f"{', '.join(t.topic for t in truths[1:])}")
    tf_topics = {t.topic for t in by_type.get(rb.TF, [])}
    if "/tf_static" in tf_topics:
        s["topics.tf_static"] = "/tf_static"
    elif "/tf" in tf_topics:
        s["topics.tf_static"], s["topics.tf"] = "/tf", None
        notes.append("no /tf_static: the camera mount is looked up in /tf")
    else:
        notes.append("cannot convert: no /tf_static or /tf with the camera mount (base frame → camera frame); "
                     "give it as mount=[x,y,z,qx,qy,qz,qw], the colour optical frame in the base frame")

