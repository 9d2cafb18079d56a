"""The trace's two code paths, for tests that hold them equal: the C loops of
``aquasim_py._fastcsv`` (when built) and their Python references in ``aquasim_py.trace``."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from types import ModuleType

from aquasim_py import trace

#: path name -> the module trace uses (None: the Python reference); "c" only where it was built
PATHS: dict[str, ModuleType | None] = {"python": None, **({"c": trace._fastcsv} if trace._fastcsv else {})}


@contextmanager
def using(name: str) -> Iterator[None]:
    """Run the trace on path ``name`` of :data:`PATHS` inside the block."""
    old = trace._fastcsv
    trace._fastcsv = PATHS[name]
    try:
        yield
    finally:
        trace._fastcsv = old
