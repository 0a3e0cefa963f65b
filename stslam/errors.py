"""Project exceptions.

Every error a user can cause (a bad override, a bad file) is a subclass of
:class:`StslamError`; the command line prints its message on one line and exits
with a non-zero code, without a traceback. Messages name the parameter, file
(and line) or topic at fault and say what was expected.
"""

from __future__ import annotations


class StslamError(Exception):
    """Base class of every error the project raises on purpose."""


class ConfigError(StslamError, ValueError):
    """A configuration value is missing, of the wrong type or out of range."""


class InputFileError(StslamError, ValueError):
    """A user-supplied file cannot be read as the expected format.

    Parameters
    ----------
    path : str
        The file at fault.
    problem : str
        What is wrong and what was expected.
    line : int, optional
        1-based line number in the file, when the problem sits on one line.
    """

    def __init__(self, path, problem: str, line: int | None = None):
        self.path = str(path)
        self.line = line
        self.problem = problem
        where = f"{self.path}:{line}" if line is not None else self.path
        super().__init__(f"{where}: {problem}")


class DegenerateFitError(StslamError, ValueError):
    """A structure fit cannot be made from the given window (SPEC 2.4)."""
