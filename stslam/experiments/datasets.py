"""Generate data sets: the work behind ``experiments/make_data.py`` (SPEC 9).

A driver at the edge: it writes the data file and its preview figure. One data set
so far, ``fridge``: the fridge-door RGB-D sequence as MCAP
(:mod:`stslam.rgbd.sequence`, :mod:`stslam.io.mcap_write`) and
``<out stem>_preview.png``/``.pdf`` beside it.
"""

from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from stslam.errors import ConfigError
from stslam.rgbd.sequence import DataRequest, FridgeSequence
from stslam.io.mcap_write import write_fridge_mcap
from stslam.render.fridge_sequence import sequence_preview

PREVIEW_FRAMES = 4


@dataclass(frozen=True)
class GenerationReport:
    """What was generated: the data file, its previews, frame count, size (bytes) and time taken (s)."""

    path: Path
    previews: tuple[Path, ...]
    n_frames: int
    size_bytes: int
    seconds: float

    def lines(self) -> list[str]:
        return [f"wrote {self.path} ({self.n_frames} frames, {self.size_bytes / 2**20:.1f} MiB) "
                f"in {self.seconds:.1f} s",
                "preview: " + ", ".join(str(p) for p in self.previews)]


def _save_figure(figure, path: Path) -> None:
    """Save ``figure`` to ``path`` through a temporary file, so a reader never sees half a file."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}{path.suffix}")
    try:
        figure.savefig(tmp, dpi=110, metadata={"CreationDate": None} if path.suffix == ".pdf" else None)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


def fridge_preview(sequence: FridgeSequence, n_samples: int = PREVIEW_FRAMES):
    """Preview figure of ``sequence`` from ``n_samples`` evenly spaced frames (re-rendered, identical)."""
    indices = np.unique(np.linspace(0, len(sequence) - 1, n_samples).round().astype(int))
    frames = [sequence.frame(int(k)) for k in indices]
    return sequence_preview([f.t_s for f in frames], [f.rgb for f in frames], [f.depth_m for f in frames],
                            sequence.times_s, sequence.door_angles_rad, sequence.poses_gt_xytheta,
                            sequence.poses_odom_xytheta, sequence.hinge_point_world,
                            max_depth_m=sequence.config.depth_max_m)


def generate(request: DataRequest) -> GenerationReport:
    """Generate the data set of ``request``; ConfigError when its file exists and may not be replaced."""
    path, config, encoding, seed = request.out, request.sequence, request.depth_encoding, request.seed
    if path.exists() and not request.overwrite:
        raise ConfigError(f"out: {path} already exists; pass overwrite=true to replace it")

    started = time.perf_counter()
    sequence = FridgeSequence(config, seed)
    metadata = {"generator": "stslam.rgbd.sequence", "seed": seed, "depth_encoding": encoding,
                **asdict(config)}
    written = write_fridge_mcap(path, sequence, depth_encoding=encoding, overwrite=request.overwrite,
                                show_progress=request.show_progress, metadata=metadata)
    seconds = time.perf_counter() - started
    figure = fridge_preview(sequence)
    previews = tuple(path.with_name(f"{path.stem}_preview{suffix}") for suffix in (".png", ".pdf"))
    for preview in previews:
        _save_figure(figure, preview)
    return GenerationReport(path=written.path, previews=previews, n_frames=written.n_frames,
                            size_bytes=written.size_bytes, seconds=seconds)
