"""The kernel's SimPy environment: ``simpy.Environment`` with its event queue in C.

SimPy keeps pending events in a list heap of ``(time, priority, sequence number, event)``
tuples. With one sleeping process per node, a network of thousands of nodes keeps thousands
of them, and every sift of a push or pop follows pointers to scattered tuples and floats:
the cost per event grows with the network (docs/performance.md, scaling).
:class:`Environment` keeps the same keys inside the entries of one C array
(``aquasim_py._events.Queue``) and runs ``step`` and ``schedule`` in C. The order of events
is SimPy's, key for key, so a run gives the same trace on either environment.

Without the compiled extension (no C compiler at install), :func:`environment` gives
``simpy.Environment`` itself.
"""

from __future__ import annotations

from importlib.metadata import version
from typing import Any

import simpy

try:  # the optional C extension (setup.py); None without it
    from . import _events
except ImportError:  # pragma: no cover - exercised only on installs without a compiler
    _events = None  # type: ignore[assignment]


def _simpy_requeues() -> bool:
    """Whether the installed SimPy's ``step`` reschedules an event's remaining callbacks when
    one of them stops the run (4.1.2 and later; 4.1.0 and 4.1.1 let the exception drop them)."""
    try:
        parts = tuple(int(p) for p in version("simpy").split(".")[:3])
    except ValueError:  # a pre-release or local tag: take the newer behaviour
        return True
    return parts >= (4, 1, 2)


#: the installed SimPy's StopSimulation handling, which :class:`Environment` follows
SIMPY_REQUEUES = _simpy_requeues()


class Environment(simpy.Environment):
    """``simpy.Environment`` whose queue is :class:`aquasim_py._events.Queue`.

    ``schedule`` and ``step`` are the queue's (the installed SimPy 4.1.x's statement for
    statement, in C: :data:`SIMPY_REQUEUES`),
    ``_eid`` is its sequence counter and ``peek`` its first time. What SimPy's own code uses
    of an environment is unchanged; code that reads ``_queue`` as a list does not work here.
    """

    def __init__(self, initial_time: float = 0) -> None:
        if _events is None:
            raise RuntimeError("aquasim_py._events is not built (no C compiler at install)")
        super().__init__(initial_time)
        queue = _events.Queue(self, SIMPY_REQUEUES)
        self._queue = queue  # type: ignore[assignment]
        self._eid = queue  # type: ignore[assignment]
        # instance attributes shadow the methods: SimPy's events call them with no Python
        # frame in between
        self.schedule = queue.schedule  # type: ignore[method-assign]
        self.step = queue.step  # type: ignore[method-assign]

    def peek(self) -> Any:
        return self._queue.peek()  # type: ignore[attr-defined]


#: whether :func:`environment` gives the compiled :class:`Environment` (tests switch it off to
#: run the kernel on SimPy's own)
compiled = True


def environment() -> simpy.Environment:
    """The kernel's environment: :class:`Environment` when the extension is built and
    :data:`compiled` is set, else ``simpy.Environment``."""
    if compiled and _events is not None:
        return Environment()
    return simpy.Environment()
