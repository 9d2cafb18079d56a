"""Plain result rows: JSON-safe values and CSV with exact float text.

A leaf module (it imports nothing of aquasim_py), shared by the runner (``summary.json``,
``variants.csv``) and sweeps (``sweep.csv``, run keys, ``sweep.json``).
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

__all__ = ["json_safe", "rows_to_csv"]


def json_safe(v: Any) -> Any:
    """Plain JSON data: NaN / inf -> None (strict JSON has neither), numpy scalars -> Python."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: json_safe(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [json_safe(x) for x in v]
    if hasattr(v, "item") and callable(v.item):  # numpy scalars
        return json_safe(v.item())
    return v


def _cell(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, float):
        return "nan" if math.isnan(v) else repr(float(v))  # repr round-trips exactly
    if isinstance(v, (list, dict)):
        return json.dumps(v)
    return v


def rows_to_csv(rows: Sequence[dict[str, Any]], cols: Sequence[str], path: str | Path) -> None:
    """Write rows (missing metrics left empty) with exact float text."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(cols)
        for r in rows:
            w.writerow([_cell(r.get(c)) for c in cols])
