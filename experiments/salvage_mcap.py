"""Keep the complete messages of a damaged or unfinished MCAP recording as a new, readable file.

    python experiments/salvage_mcap.py <damaged.mcap> <new.mcap> [--overwrite]

The work is :func:`stslam.io.mcap_salvage.salvage_mcap`; this is its command line. The damaged
file is only read; the new one appears only when complete, and an existing one is replaced only
with ``--overwrite``. Prints what was kept per topic and what was left out or where reading stopped.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from stslam.errors import StslamError
from stslam.io.mcap_salvage import salvage_mcap


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("source", help="the damaged or unfinished MCAP file (only read)")
    parser.add_argument("target", help="the new MCAP file to write")
    parser.add_argument("--overwrite", action="store_true", help="replace target if it exists")
    args = parser.parse_args(argv)
    if Path(args.target).exists() and not args.overwrite:
        print(f"error: {args.target}: already exists; pass --overwrite to replace it", file=sys.stderr)
        return 2
    try:
        report = salvage_mcap(args.source, args.target, overwrite=args.overwrite)
    except StslamError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted: no output file was written", file=sys.stderr)
        return 130
    for line in report.lines():
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
