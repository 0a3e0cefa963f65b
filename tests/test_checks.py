"""stslam.checks: ValueError naming the argument, with the config readers' range wording."""

from dataclasses import dataclass

import pytest

from stslam.checks import check_choice, check_fields, check_int, check_number


@dataclass(frozen=True)
class _Settings:
    angle: float = 10.0
    ratio: float = 0.5


def test_check_number_names_the_argument_and_the_bounds():
    assert check_number("sigma", 2) == 2.0
    with pytest.raises(ValueError, match=r"^sigma: expected a finite number > 0 and ≤ 1, got 1.5$"):
        check_number("sigma", 1.5, low=0, low_open=True, high=1)
    for bad in (float("nan"), float("inf"), True, "x"):
        with pytest.raises(ValueError, match=r"^sigma: expected a finite number"):
            check_number("sigma", bad)


def test_check_int_and_choice():
    assert check_int("n", 3, low=2) == 3
    for bad in (1, 2.0, True):
        with pytest.raises(ValueError, match=r"^n: expected an integer ≥ 2, got"):
            check_int("n", bad, low=2)
    with pytest.raises(ValueError, match=r"^mode: expected one of a, b; got 'c'$"):
        check_choice("mode", "c", ("a", "b"))


@pytest.mark.parametrize("fields, message", [
    ({"angle": "(0, 90]"}, None),
    ({"angle": "(10, 90]"}, r"^angle: expected a finite number > 10.0 and ≤ 90.0, got 10.0$"),
    ({"angle": "[10, 10]", "ratio": "[0, 1)"}, None),
    ({"ratio": "(0.5, inf)"}, r"^ratio: expected a finite number > 0.5, got 0.5$"),
    ({"ratio": "[0, 0.5)"}, r"^ratio: expected a finite number ≥ 0.0 and < 0.5, got 0.5$"),
])
def test_check_fields_reads_open_and_closed_intervals(fields, message):
    if message is None:
        check_fields(_Settings(), **fields)
    else:
        with pytest.raises(ValueError, match=message):
            check_fields(_Settings(), **fields)
