"""How a metric appears in a run's printed console table, for tests that look for one."""

from __future__ import annotations

import math
import re

from aquasim_py.reporting import display


def assert_printed(stdout: str, k: str, v: float | None) -> None:
    """Metric ``k`` of value ``v`` is in a run's printed table as printed: under its family's
    heading, its name without the family with its unit and its value in that unit; or named
    in the note of the metrics printed once because another one has the same values."""
    once = next((line for line in stdout.splitlines() if line.startswith("equal, printed once:")), "")
    if re.search(rf"(^|[ ;:]){re.escape(k)} = ", once):
        return
    shown, (cell,) = display.format_row(k, [v if v is not None else math.nan])
    family, _, rest = shown.partition(".")
    assert re.search(rf"│ {re.escape(family)} +│", stdout), (k, family)
    assert re.search(rf"│   {re.escape(rest)} +│ +{re.escape(cell)} │", stdout), (k, shown, cell)
