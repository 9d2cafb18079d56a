"""The trace's bulk loops in C (aquasim_py/_fastcsv.c); their Python references are in trace.py."""

from typing import Any

def csv_rows(columns: list[tuple[str, Any, Any]], n: int) -> bytes:
    """The CSV lines (UTF-8) of ``n`` rows, as ``trace._csv_lines`` writes them; ``columns``:
    ``("f", float64 buffer, None)``, ``("i", int64 buffer, None)``, ``("c", int32 codes, list of
    each category's field)`` or ``("s", list of the n fields, None)``."""

def push_rows(rows: list[tuple[Any, ...]], columns: list[tuple[str, Any, dict[Any, int]]]) -> list[int]:
    """Append row tuples to typed columns ``(kind, data, cats)`` as ``_Column.push_many`` would;
    returns the indices of the columns left untouched (values the fast path does not take)."""

def fast_repr(v: float) -> str | None:
    """``float.__repr__(v)`` by csv_rows' own formatter (2^-10 <= |v| < 2^51); None elsewhere."""
