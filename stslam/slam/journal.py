"""A state's journal: the changes to its layout, kept so a replay can redo them (SPEC 18).

An EKF state (:class:`~stslam.slam.core.SlamState`, the body state of
:mod:`stslam.slam.bodies.state`) is changed between its predictions and
updates by A-SLAM's decisions: a landmark added, converted to another block,
restarted, made a body's member or detached from it. Each method making such
a change is :func:`journaled`: while the state has a ``journal`` (an object
with ``log(state, name, args, kwargs)``, :class:`stslam.slam.replay.ReplayHistory`),
the call is reported to it after it ran, with its arguments, and a replay
from an older state calls the same methods again with the same arguments.
Calls made inside a journaled call belong to it and are not reported.
A state copy has no journal.
"""

from __future__ import annotations

from functools import wraps

import numpy as np

__all__ = ["journaled"]


def journaled(method):
    """Report each outermost call of ``method`` to the state's ``journal``, if any (module docstring)."""
    name = method.__name__

    @wraps(method)
    def call(self, *args, **kwargs):
        journal = self.__dict__.get("journal")
        if journal is None:
            return method(self, *args, **kwargs)
        self.journal = None  # the calls it makes are part of this one
        try:
            result = method(self, *args, **kwargs)
        finally:
            self.journal = journal
        journal.log(self, name, tuple(map(_kept, args)), {key: _kept(a) for key, a in kwargs.items()})
        return result

    return call


def _kept(value):
    """An argument as the journal keeps it: arrays copied (a caller may reuse its buffers after the call)."""
    return np.array(value) if isinstance(value, np.ndarray) else value
