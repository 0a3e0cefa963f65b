"""The benchmark's kernel warm-up (stslam.experiments.kernels) makes every compiled kernel's first call from
Python: A-SLAM in the kitchen (bodies, window evidence, pair tests) and in square_centred then compiles
nothing more, so no timed measure of experiments/bench.py pays a compilation."""

from __future__ import annotations

import subprocess
import sys

from conftest import REPO

# Run in a fresh interpreter: in this one, earlier tests have long since called every kernel.
SCRIPT = r"""
import importlib, pkgutil, sys
sys.path.insert(0, "experiments")
from numba.core.registry import CPUDispatcher
import stslam
from bench import marker_track_settings, slam_config
from stslam.experiments.kernels import kernel_warmup_s

def compiled():
    out = {}
    for info in pkgutil.walk_packages(stslam.__path__, "stslam."):
        module = sys.modules.get(info.name)
        for name, obj in vars(module or object).items():
            if isinstance(obj, CPUDispatcher) and obj.__module__ == info.name:
                out[f"{info.name}.{name}"] = set(map(str, obj.signatures))
    return out

kernel_warmup_s(marker_track_settings())
before = compiled()
from stslam.config.robot import sensor_from_config
from stslam.config.sim import world_from_config
from stslam.experiments.dynamic_slam import method_runners
from stslam.slam.evaluation import run_seed
for world_name in ("kitchen", "square_centred"):
    cfg = slam_config(f"world={world_name}", "methods=[a_slam]")
    world = world_from_config(cfg)
    runners = method_runners(cfg, ["a_slam"], world)
    run_seed(world, sensor_from_config(cfg), bool(cfg["robot"]["control_noise"]), runners, 0)
after = compiled()
new = {name: sorted(after[name] - before.get(name, set())) for name in after if after[name] - before.get(name, set())}
print(repr(new))
"""


def test_after_the_warm_up_a_slam_compiles_no_kernel_of_its_own():
    done = subprocess.run([sys.executable, "-c", SCRIPT], cwd=REPO, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().splitlines()[-1] == "{}", done.stdout  # kernel → signatures first compiled later
