"""How every entry script in ``experiments/`` ends on a user's error or an interruption (SPEC 12).

A bad override, value or input file ends the script with one line on stderr,
``error: <parameter or file[:line]>: <what was expected>``, and exit code 2
(:class:`~stslam.errors.StslamError`, omegaconf's errors and Hydra's
composition errors, each made one line); Ctrl-C or SIGTERM (``kill``, a
scheduler's cancel) with ``interrupted: <what was not written>`` and exit code
130 (also when compiled code turned the interrupt into another exception chained to it). Any
other exception is a bug and keeps its traceback.
"""

from __future__ import annotations

import functools
import signal
import sys
import threading
from pathlib import Path

from hydra.errors import ConfigCompositionException, HydraException, MissingConfigException, OverrideParseException
from omegaconf.errors import ConfigAttributeError, OmegaConfBaseException

from stslam.errors import StslamError

EXIT_ERROR = 2
EXIT_INTERRUPTED = 130


def one_line(error: BaseException, conf_dir: Path | None = None) -> str:
    """Hydra's (multi-line) composition error, or any other, as one line naming the key or group.

    ``conf_dir`` (the config folder) adds its options of a group to the message for an unknown option.
    """
    if isinstance(error, OverrideParseException):
        detail = [line.strip() for line in str(error).splitlines()
                  if line.strip() not in ("", "^")
                  and not line.startswith(("Error parsing override", "LexerNoViableAlt", "See https"))]
        because = f" ({detail[0]})" if detail else ""
        return f"override {error.override!r}: cannot parse it{because}; expected key=value"
    full_key = getattr(error.__cause__, "full_key", None)
    if isinstance(error, ConfigCompositionException) and isinstance(error.__cause__, ConfigAttributeError) \
            and full_key:
        return f"{full_key}: no such parameter in the configuration"
    if isinstance(error, MissingConfigException) and getattr(error, "missing_cfg_file", None):
        group, _, option = error.missing_cfg_file.rpartition("/")
        options = {p.stem for p in (conf_dir / group).glob("*.yaml")} if group and conf_dir else set()
        # Hydra's own groups (hydra/launcher …) have options in packages too: take those it lists.
        listed = str(error).partition("Available options")[2].partition("Config search path")[0]
        options = sorted(options | {line.strip() for line in listed.splitlines()[1:] if line.strip()})
        expected = f"; expected one of {', '.join(options)}" if options else ""
        return f"{group or 'config'}: no config named {option!r}{expected}"
    lines = [line.strip() for line in str(error).splitlines()]
    lines = [line for line in lines if line and not line.startswith(("See https", "Config search path"))
             and not line.startswith("provider=")]
    if error.__cause__ is not None:
        lines.append(str(error.__cause__).splitlines()[0])
    return "; ".join(lines)


def error_line(error: BaseException, conf_dir: Path | None = None) -> str | None:
    """The ``error:`` line's message for an error the user caused; None for any other exception."""
    if isinstance(error, StslamError):
        return str(error)
    if isinstance(error, OmegaConfBaseException):
        key = getattr(error, "full_key", None) or ""
        return f"{key + ': ' if key else ''}{str(error).splitlines()[0]}"
    if isinstance(error, HydraException):
        return one_line(error, conf_dir)
    return None


def _raise_interrupt(signum, frame) -> None:
    """SIGTERM ends the script like Ctrl-C, so that temporaries are removed on the way out."""
    raise KeyboardInterrupt


def caused_by_interrupt(error: BaseException) -> bool:
    """Whether an exception comes from Ctrl-C or SIGTERM: a KeyboardInterrupt raised inside compiled code
    (numba's dispatcher, numpy's comparisons) can surface as another exception chained to it."""
    seen = set()
    while error is not None and id(error) not in seen:
        if isinstance(error, KeyboardInterrupt):
            return True
        seen.add(id(error))
        error = error.__cause__ or error.__context__
    return False


def main_guard(interrupted: str, conf_dir: Path | None = None):
    """Decorator of an entry point: user errors and interruptions end it as the module docstring says.

    ``interrupted`` completes the line ``interrupted: …`` (what was not written); ``conf_dir`` is
    the config folder, named in an unknown group option's message. Inside ``@hydra.main`` it must be
    the inner decorator (Hydra would report the errors itself otherwise).
    """
    def decorate(fn):
        @functools.wraps(fn)
        def guarded(*args, **kwargs):
            main_thread = threading.current_thread() is threading.main_thread()
            previous = signal.signal(signal.SIGTERM, _raise_interrupt) if main_thread else None
            try:
                return fn(*args, **kwargs)
            except KeyboardInterrupt:
                print(f"interrupted: {interrupted}", file=sys.stderr)
                sys.exit(EXIT_INTERRUPTED)
            except Exception as error:  # noqa: BLE001 - only user errors are turned into a line
                if caused_by_interrupt(error):
                    print(f"interrupted: {interrupted}", file=sys.stderr)
                    sys.exit(EXIT_INTERRUPTED)
                line = error_line(error, conf_dir)
                if line is None:
                    raise
                print(f"error: {line}", file=sys.stderr)
                sys.exit(EXIT_ERROR)
            finally:
                if main_thread:
                    signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)
        return guarded
    return decorate
