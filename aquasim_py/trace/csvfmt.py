"""CSV text of a table's chunk, byte for byte what ``DataFrame.to_csv`` writes for it.

Floats are written with Python's shortest round-trip representation (``repr``), which is
exact and platform independent, so the same run gives byte-identical CSV files.
"""

from __future__ import annotations

import csv
import io
from typing import Any

import numpy as np
import pandas as pd

try:  # the trace's bulk loops in C (setup.py); without a compiler, their Python references run
    from aquasim_py import _fastcsv as fastcsv
except ImportError:  # pragma: no cover - depends on the build
    fastcsv = None  # type: ignore[assignment]

__all__ = ["QUOTED_MAX", "csv_bytes", "csv_lines", "fastcsv"]

#: the optional compiled module (aquasim_py/_fastcsv.c, built when a C compiler is there at
#: install) that formats CSV rows (:func:`csv_bytes`) and moves row tuples into columns
#: (``Table``) in C; None without it: the Python references here run, with the same bytes

#: strings whose CSV field text a sink remembers (category values: a handful per column)
QUOTED_MAX = 65_536


def _csv_field(s: str) -> str:
    """``s`` as ``csv.writer`` writes it in a row of several fields (QUOTE_MINIMAL, the dialect
    ``DataFrame.to_csv`` uses): asked of the csv module itself, so its quoting rules apply."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow([s, "x"])
    return buf.getvalue()[:-3]  # without ",x\n"


def _float_fields(cols: list[np.ndarray]) -> list[list[str]]:
    """The fields ``DataFrame.to_csv`` writes for float64 columns: numpy's ``astype(str)``,
    which gives the digits of Python's ``repr`` (shortest round trip; tests/test_trace_csv.py
    holds the two equal), and "" for NaN. ``repr`` costs about 0.45 us per value, so each
    distinct value of the chunk (by its bits: -0.0 is not 0.0) is formatted once: a static
    link's delay and SNR recur with every packet on it, a perfect clock's reading is the time.
    (pandas' hash-based factorize finds them in about half the time of a sort.)"""
    n = len(cols[0])
    inv, u = pd.factorize(np.concatenate([c.view(np.int64) for c in cols]))
    values = u.view(np.float64)
    text = np.empty(len(u), dtype=object)
    text[:] = list(map(float.__repr__, values.tolist()))
    text[np.isnan(values)] = ""
    fields = text[inv]
    return [fields[i * n : (i + 1) * n].tolist() for i in range(len(cols))]


def _int_fields(a: np.ndarray) -> list[str]:
    """The fields ``DataFrame.to_csv`` writes for an int64 column (``str`` of each value);
    through a table of the range's texts when the range is no wider than the column (ids,
    counts, uids of one chunk)."""
    lo, hi = int(a.min()), int(a.max())
    if hi - lo < len(a):
        table = np.empty(hi - lo + 1, dtype=object)
        table[:] = list(map(str, range(lo, hi + 1)))
        return table[a - lo].tolist()
    return list(map(int.__repr__, a.tolist()))


_OBJECT_TYPES = frozenset((str, type(None), bool))


def _object_fields(values: list[Any], quoted: dict[Any, str]) -> list[str] | None:
    """The fields ``DataFrame.to_csv`` writes for an object column of strings, None and bools
    ("" for None, csv quoting for strings, ``str`` for bools); None if it holds anything else
    (NaN, numbers, arrays: pandas' and csv's own rules then apply, through pandas).

    ``quoted`` maps each value met so far to its field (no other types share a key with
    these: 1 == True is excluded by the type test), so a column is one C-level ``map``."""
    if not _OBJECT_TYPES.issuperset(map(type, values)):
        return None
    try:
        return list(map(quoted.__getitem__, values))
    except KeyError:
        for v in set(values).difference(quoted):
            quoted[v] = "" if v is None else str(v) if type(v) is bool else _csv_field(v)
        return list(map(quoted.__getitem__, values))


def csv_lines(
    labels: list[str], columns: list[tuple[str, Any, list[Any]]], n: int, header: bool, quoted: dict[Any, str]
) -> str | None:
    """The CSV text of ``n`` rows given as columns (kind, values, categories) as in
    :class:`_Chunk`, byte for byte what ``DataFrame.to_csv`` writes for them, formatted a
    column at a time instead of through pandas' per-field path (about 5 us per ``packets``
    row there, 1-2 us here). ``quoted`` caches string
    fields across calls. None when an object column holds something other than strings /
    None / bools, for a single column (csv writes an empty lone field as ``""``) and for no
    rows: the caller then uses pandas."""
    if n == 0 or len(labels) < 2:
        return None
    cols: list[list[str] | None] = [None] * len(labels)
    floats: dict[int, np.ndarray] = {}
    for i, (kind, a, cats) in enumerate(columns):
        if kind == "f":
            floats[i] = a
        elif kind == "i":
            cols[i] = _int_fields(a)
        elif kind == "c":  # each category's field once, then one take by the codes
            table = np.empty(len(cats), dtype=object)
            table[:] = _object_fields(cats, quoted)
            cols[i] = table[a].tolist()
        else:
            cols[i] = _object_fields(a, quoted)
            if cols[i] is None:
                return None
    if floats:
        for i, f in zip(floats, _float_fields(list(floats.values()))):
            cols[i] = f
    rows = "\n".join(map(",".join, zip(*cols))) + "\n"
    return _header_line(labels, quoted) + rows if header else rows


def _header_line(labels: list[str], quoted: dict[Any, str]) -> str:
    return ",".join([quoted.get(c) or _csv_field(c) for c in labels]) + "\n"


def csv_bytes(
    labels: list[str], columns: list[tuple[str, Any, list[Any]]], n: int, header: bool, quoted: dict[Any, str]
) -> bytes | None:
    """:func:`csv_lines`' text as UTF-8 bytes (None where it declines), the rows formatted in
    C when the module is built (``fastcsv.csv_rows``: each distinct float's ``repr`` once,
    ints, fields of strings prepared here as :func:`_object_fields` makes them, one buffer).
    tests/test_trace_csv.py holds both paths equal to ``DataFrame.to_csv``."""
    if fastcsv is None or n == 0 or len(labels) < 2:
        text = csv_lines(labels, columns, n, header, quoted)
        return None if text is None else text.encode("utf-8")
    cols: list[tuple[str, Any, Any]] = []
    for kind, a, cats in columns:
        if kind in "fi":
            cols.append((kind, a, None))
        elif kind == "c":
            cols.append(("c", a, _object_fields(cats, quoted)))
        else:
            fields = _object_fields(a, quoted)
            if fields is None:
                return None
            cols.append(("s", fields, None))
    rows = fastcsv.csv_rows(cols, n)
    return _header_line(labels, quoted).encode("utf-8") + rows if header else rows
