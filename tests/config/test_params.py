"""Checked config access for positive values and probabilities (stslam.config.readers)."""

from __future__ import annotations

import pytest

from stslam.errors import ConfigError
from stslam.config.readers import get_positive, get_probability

CFG = {"sigma": 0.04, "sigma_int": 2, "zero": 0.0, "neg": -0.1, "text": "abc", "flag": True,
       "inf": float("inf"), "selection": {"tau": 0.6, "one": 1.0, "low": 0, "nan": float("nan")}}


def test_positive_accepts_positive_numbers_as_float():
    assert get_positive(CFG, "sigma") == 0.04
    value = get_positive(CFG, "sigma_int")
    assert value == 2.0 and isinstance(value, float)
    assert get_positive(CFG, "absent", default=0.5) == 0.5


@pytest.mark.parametrize("key, message", [
    ("zero", r"^zero: expected a number > 0.0, got 0.0$"),
    ("neg", r"^neg: expected a number > 0.0, got -0.1$"),
    ("text", r"^text: expected a number, got 'abc'$"),
    ("flag", r"^flag: expected a number, got True$"),
    ("inf", r"^inf: expected a finite number, got inf$"),
    ("absent", r"^absent: missing from the configuration$"),
])
def test_positive_rejects(key, message):
    with pytest.raises(ConfigError, match=message):
        get_positive(CFG, key)


def test_probability_accepts_the_open_interval():
    assert get_probability(CFG, "selection.tau") == 0.6
    assert get_probability(CFG, "selection.absent", default=0.6) == 0.6


@pytest.mark.parametrize("key, message", [
    ("selection.one", r"^selection\.one: expected a probability > 0.0 and < 1.0, got 1.0$"),
    ("selection.low", r"^selection\.low: expected a probability > 0.0 and < 1.0, got 0.0$"),
    ("neg", r"^neg: expected a probability > 0.0 and < 1.0, got -0.1$"),
    ("selection.nan", r"^selection\.nan: expected a finite number, got nan$"),
    ("text", r"^text: expected a number, got 'abc'$"),
])
def test_probability_rejects(key, message):
    with pytest.raises(ConfigError, match=message):
        get_probability(CFG, key)
