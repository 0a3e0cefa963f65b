"""Write synthetic furniture tracks for classify_tracks (SPEC 10):

    python experiments/make_tracks.py out=data/tracks n=100 seed=0 [time_column=false] [rate_hz=30]

One file per track, ``<out>/track_<i>_<kind>.txt``, cycling through doors,
cabinet doors, dishwasher doors and drawers; each starts with ``# key: value``
lines holding its ground truth (true_model, onset_s, …). Then classify them:

    python experiments/run.py +exp=classify_tracks tracks='data/tracks/*.txt'
"""

from __future__ import annotations

import sys

from stslam.errors import ConfigError
from stslam.experiments.cli import main_guard
from stslam.io.track_files import format_track, write_track_file
from stslam.sim.track_generator import generate_tracks

DEFAULTS = {"out": None, "n": "100", "seed": "0", "time_column": "false", "rate_hz": "30"}


def parse_args(argv: list[str]) -> dict:
    """``key=value`` arguments over :data:`DEFAULTS`; ConfigError naming a bad one."""
    args = dict(DEFAULTS)
    for item in argv:
        key, sep, value = item.partition("=")
        if not sep or key not in DEFAULTS:
            raise ConfigError(f"{item}: expected one of {', '.join(k + '=…' for k in DEFAULTS)}")
        args[key] = value
    if not args["out"]:
        raise ConfigError("out: the folder to write into is required (out=<folder>)")
    for key in ("n", "seed"):
        if not args[key].isdigit() or (key == "n" and int(args[key]) < 1):
            raise ConfigError(f"{key}: expected a non-negative integer{' ≥ 1' if key == 'n' else ''}, got {args[key]!r}")
    if args["time_column"] not in ("true", "false"):
        raise ConfigError(f"time_column: expected true or false, got {args['time_column']!r}")
    try:
        if float(args["rate_hz"]) <= 0:
            raise ValueError
    except ValueError:
        raise ConfigError(f"rate_hz: expected a number > 0, got {args['rate_hz']!r}") from None
    return args


@main_guard("the tracks written so far are kept; the folder may be incomplete")
def main(argv: list[str]) -> int:
    args = parse_args(argv)
    tracks = generate_tracks(int(args["n"]), int(args["seed"]), rate_hz=float(args["rate_hz"]))
    with_time = args["time_column"] == "true"
    for i, track in enumerate(tracks):
        text = format_track(track.points_world, track.times_s if with_time else None, track.metadata())
        write_track_file(f"{args['out']}/track_{i:03d}_{track.kind}.txt", text)
    print(f"wrote {len(tracks)} tracks to {args['out']}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
