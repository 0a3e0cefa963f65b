"""List what a ROS bag holds and the ``convert.py`` command that would read it.

    python experiments/survey_bag.py <rec.bag or ROS 2 bag folder> [--out data/rec.mcap]

The work is :func:`stslam.io.bag_survey.survey_bag`; this is its command line. The bag is
only read. Prints one line per topic (type, count, rate, frame, image encoding), notes on
what was chosen or is missing, and the command. Exit code 2 for a bag that cannot be read,
1 when a topic the conversion needs is missing.
"""

from __future__ import annotations

import argparse
import sys

from stslam.errors import StslamError
from stslam.io.bag_survey import survey_bag


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag", help="a ROS 1 .bag file or a ROS 2 bag folder (only read)")
    parser.add_argument("--out", default="data/rec.mcap", help="the MCAP the suggested command writes")
    args = parser.parse_args(argv)
    try:
        survey = survey_bag(args.bag)
    except StslamError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    for line in survey.lines(args.out):
        print(line)
    return 1 if any(note.startswith("cannot convert") for note in survey.notes) else 0


if __name__ == "__main__":
    sys.exit(main())
