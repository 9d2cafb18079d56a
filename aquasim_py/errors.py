"""The scenario mistakes and warnings the ``aquasim-py`` command prints as one line each:
:class:`ScenarioError`, :class:`ScenarioWarning` and :class:`ScenarioDeprecationWarning`.

A leaf module (standard library only), so that the command can catch and filter them before
it has loaded anything heavy (``aquasim-py --version`` loads neither numpy nor pydantic).
:mod:`aquasim_py.scenario`, which raises them, re-exports all three.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

__all__ = ["ScenarioDeprecationWarning", "ScenarioError", "ScenarioWarning"]


class ScenarioError(Exception):
    """A mistake in a scenario (or its overrides): which file, which key, what is wrong."""

    def __init__(self, file: str | Path | None, key_path: str, message: str) -> None:
        self.file = str(file) if file is not None else "<scenario>"
        self.key_path = key_path
        self.message = message
        super().__init__(str(self))

    def __reduce__(self) -> tuple[Any, ...]:  # picklable across worker processes
        return (type(self), (self.file, self.key_path, self.message))

    def __str__(self) -> str:
        parts = [self.file]
        if self.key_path:
            parts.append(self.key_path)
        parts.append(self.message)
        return ": ".join(parts)


class ScenarioWarning(UserWarning):
    """An implausible but legal scenario value; the CLI prints it as one ``warning:`` line."""


class ScenarioDeprecationWarning(DeprecationWarning):
    """A scenario uses a deprecated name; the CLI prints it as one ``warning:`` line."""
