"""Every figure a reporting test saves is checked as it is written: every labelled series can
be seen, no legend covers a data point, no tick labels overlap (:mod:`readable`, written apart
from the code that makes it so, and :func:`aquasim_py.reporting.figures.problems`, which also
checks drawn paths between the points)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import matplotlib.figure
import pytest
from readable import findings  # tests/reporting, beside this file

from aquasim_py.reporting import figures


@pytest.fixture(autouse=True)
def checked_figures(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[str]]:
    """Check every figure saved during the test; fail the test on any finding."""
    saved: list[str] = []
    found: list[str] = []
    write = matplotlib.figure.Figure.savefig

    def savefig(fig: Any, path: Any, *args: Any, **kwargs: Any) -> Any:
        found.extend(f"{path}: {problem}" for problem in findings(fig) + figures.problems(fig))
        saved.append(str(path))
        return write(fig, path, *args, **kwargs)

    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", savefig)
    yield saved
    assert not found, "\n".join(found)
