"""Draw one frame of a scene.mcap: ``python experiments/scene_view.py <scene.mcap> <out.png> [frame]``.

A stand-in for Foxglove's 3D and image panels (SPEC 15): a top view of the paths,
landmarks coloured by model and joints, and the camera image with tracked corners.
"""

from __future__ import annotations

import sys

from stslam.errors import StslamError
from stslam.io.scene_read import read_scene_frame
from stslam.render.scene import scene_figure

USAGE = "usage: python experiments/scene_view.py <scene.mcap> <out.png> [frame (default: the last)]"


def main(argv: list[str]) -> int:
    if len(argv) not in (2, 3) or (len(argv) == 3 and not argv[2].lstrip("-").isdigit()):
        print(f"error: {USAGE}", file=sys.stderr)
        return 2
    try:
        snapshot = read_scene_frame(argv[0], int(argv[2]) if len(argv) == 3 else None)
        scene_figure(snapshot).savefig(argv[1], dpi=110)
    except StslamError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:
        print(f"error: {argv[1]}: cannot write the figure ({error.strerror or error})", file=sys.stderr)
        return 2
    print(f"wrote {argv[1]} (frame {snapshot.frame} of {snapshot.n_frames})")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
