"""Merging the jobs of a Hydra multirun sweep into one table (pure; I/O in experiments/aggregate.py)."""

from __future__ import annotations

import pandas as pd

from stslam.eval.stats import SUMMARY_COLUMNS, summarise

NOT_SWEPT = {"seed", "out_dir", "progress"}


def parse_overrides(overrides: list[str]) -> dict[str, str]:
    """``["a.b=1", "+exp=x"]`` → ``{"a.b": "1", "exp": "x"}`` (leading ``+``/``~`` dropped)."""
    out = {}
    for item in overrides:
        key, sep, value = item.partition("=")
        if sep:
            out[key.lstrip("+~")] = value
    return out


def swept_keys(job_overrides: list[dict[str, str]]) -> list[str]:
    """Keys whose values differ between jobs, except the seed and output options."""
    keys = sorted({k for job in job_overrides for k in job})
    return [k for k in keys if k not in NOT_SWEPT
            and len({job.get(k) for job in job_overrides}) > 1]


def merge_jobs(job_overrides: list[dict[str, str]], job_metrics: list[pd.DataFrame]) -> tuple[pd.DataFrame, list[str]]:
    """Concatenate per-job metrics, adding one column per swept key.

    Returns the merged table (swept columns first, then ``seed, method, …``)
    and the swept keys.
    """
    if len(job_overrides) != len(job_metrics):
        raise ValueError("one overrides dict per metrics table expected")
    keys = swept_keys(job_overrides)
    frames = []
    for overrides, metrics in zip(job_overrides, job_metrics):
        frame = metrics.copy()
        for position, key in enumerate(keys):
            frame.insert(position, key, overrides.get(key))
        frames.append(frame)
    merged = pd.concat(frames, ignore_index=True)
    return merged, keys


def summarise_sweep(merged: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """``summary.csv`` of a sweep: one block per combination of swept values (SPEC 12 columns after them)."""
    if not keys:
        return summarise(merged)
    blocks = []
    for values, group in merged.groupby(keys, sort=False):
        values = values if isinstance(values, tuple) else (values,)
        block = summarise(group.drop(columns=keys))
        for position, (key, value) in enumerate(zip(keys, values)):
            block.insert(position, key, value)
        blocks.append(block)
    return pd.concat(blocks, ignore_index=True) if blocks else pd.DataFrame(columns=keys + SUMMARY_COLUMNS)
