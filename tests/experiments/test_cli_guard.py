"""The entry scripts' guard (stslam.experiments.cli): an interrupt that compiled code turned into another
exception still ends the run as an interruption; any other exception keeps its traceback."""

from __future__ import annotations

import pytest

from stslam.experiments.cli import EXIT_INTERRUPTED, caused_by_interrupt, main_guard


def _from_compiled_code():
    # What numba's dispatcher does when Ctrl-C arrives while it runs: a SystemError chained to the interrupt.
    try:
        raise KeyboardInterrupt
    except KeyboardInterrupt as interrupt:
        raise SystemError("CPUDispatcher(...) returned a result with an exception set") from interrupt


def test_an_interrupt_turned_into_another_exception_ends_as_an_interruption(capsys):
    guarded = main_guard("no results folder was written")(_from_compiled_code)
    with pytest.raises(SystemExit) as ended:
        guarded()
    assert ended.value.code == EXIT_INTERRUPTED
    assert capsys.readouterr().err == "interrupted: no results folder was written\n"


def test_other_exceptions_are_not_interruptions():
    def bug():
        try:
            raise ValueError("inner")
        except ValueError as inner:
            raise SystemError("outer") from inner

    assert caused_by_interrupt(KeyboardInterrupt())
    assert not caused_by_interrupt(SystemError("alone"))
    with pytest.raises(SystemError, match="outer"):
        main_guard("nothing")(bug)()
