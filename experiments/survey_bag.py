"""List what a recording holds and the command that reads it (``convert.py``; ``+exp=fridge`` for an MCAP).

    python experiments/survey_bag.py <rec.bag, ROS 2 bag folder or Foxglove MCAP> [--out data/rec.mcap]

The work is :func:`stslam.io.mcap_survey.survey_recording` (:mod:`stslam.io.bag_survey` for
bags, :mod:`stslam.io.mcap_survey` for protobuf MCAP files); this is its command line. The
file is only read. Prints one line per topic (type, count, rate, frame, image encoding),
notes on what was chosen or is missing, and the command. Exit code 2 for a file that cannot
be read, 1 when a topic the command needs is missing.
"""

from __future__ import annotations

import argparse
import sys

from stslam.errors import StslamError
from stslam.io.mcap_survey import survey_recording


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag", help="a ROS 1 .bag file, a ROS 2 bag folder or an MCAP file (only read)")
    parser.add_argument("--out", default="data/rec.mcap", help="the MCAP the suggested command writes")
    args = parser.parse_args(argv)
    try:
        survey = survey_recording(args.bag)
    except StslamError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    for line in survey.lines(args.out):
        print(line)
    return 1 if any(note.startswith("cannot ") for note in survey.notes) else 0


if __name__ == "__main__":
    sys.exit(main())
