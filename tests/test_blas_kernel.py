"""Importing stslam pins OpenBLAS's kernel family on x86-64 with AVX2 and FMA (stslam/__init__): one rounding
on every such machine, so a seed repeats to the bit across them."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

import stslam


def _import_and_read(env: dict) -> str:
    code = "import stslam, os; print(os.environ.get('OPENBLAS_CORETYPE', ''))"
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                          check=True).stdout.strip()


def test_the_kernel_is_haswell_where_the_processor_has_avx2_and_fma():
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    expected = "Haswell" if stslam._has_avx2_fma() else ""
    assert _import_and_read(env) == expected


def test_a_kernel_the_user_set_is_kept():
    if not stslam._has_avx2_fma():
        pytest.skip("no AVX2 and FMA here: stslam sets no kernel")
    env = {**os.environ, "OPENBLAS_CORETYPE": "SkylakeX"}
    assert _import_and_read(env) == "SkylakeX"
