"""Event tables of a run: cheap appends during the run, pandas / CSV / Parquet after.

Each table is a set of typed columns (``array.array`` for numbers, integer codes for
categorical strings, a list for anything else): appending a row costs a few list appends and
a packet trace of millions of rows stays compact. ``frames()`` turns the tables into pandas
DataFrames with the DESIGN.md columns first; ``write`` and :func:`load` round-trip them.

Floats are written with Python's shortest round-trip representation (``repr``), which is
exact and platform independent, so the same run gives byte-identical CSV files.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
import shutil
import weakref
from array import array
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pandas as pd

try:  # the trace's bulk loops in C (setup.py); without a compiler, their Python references run
    from aquasim_py import _fastcsv
except ImportError:  # pragma: no cover - depends on the build
    _fastcsv = None  # type: ignore[assignment]

__all__ = [
    "SCHEMAS",
    "Table",
    "TableNotKept",
    "Trace",
    "TraceConfig",
    "TraceFiles",
    "load",
    "read_table",
    "table_columns",
]

#: Column kinds: "f" float64, "i" int64, "c" string category (None = missing), "o" any object.
SCHEMAS: dict[str, tuple[tuple[str, str], ...]] = {
    "packets": (
        ("time", "f"),
        ("event", "c"),
        ("reason", "c"),
        ("node", "i"),
        ("src", "i"),
        ("dst", "i"),
        ("uid", "i"),
        ("kind", "c"),
        ("bits", "i"),
        ("tof", "f"),
        ("snr_db", "f"),
        ("path", "c"),
        ("local_time", "f"),
    ),
    "positions": (
        ("time", "f"),
        ("node", "i"),
        ("x", "f"),
        ("y", "f"),
        ("z", "f"),
        ("vx", "f"),
        ("vy", "f"),
        ("vz", "f"),
    ),
    "estimates": (
        ("time", "f"),
        ("node", "i"),
        ("protocol", "c"),
        ("x", "f"),
        ("y", "f"),
        ("z", "f"),
        ("true_x", "f"),
        ("true_y", "f"),
        ("true_z", "f"),
        ("error", "f"),
        ("confidence", "f"),
        ("is_reference", "o"),
    ),
    "clocks": (
        ("time", "f"),
        ("node", "i"),
        ("protocol", "c"),
        ("skew", "f"),
        ("offset", "f"),
        ("true_skew", "f"),
        ("true_offset", "f"),
        ("error", "f"),
    ),
}

# Sort key of the packets table in frames(): rows are appended when the kernel decides them
# (a reception when its last bit arrives), so the table is re-ordered by event time.
_SORT_BY = {"packets": "time", "positions": None, "estimates": None, "clocks": None}


@dataclass(frozen=True)
class TraceConfig:
    """What the trace records.

    position_interval: seconds of true time between ground-truth position samples (None or
    0 disables the ``positions`` table).
    """

    position_interval: float | None = 1.0


class _Column:
    """One typed column: "f" float64 and "i" int64 in ``array.array``, "c" strings as int32
    codes into a category list, "o" anything in a list. Degrades ("i" -> "f", anything -> "o")
    when a value does not fit.

    Numbers and codes live outside Python containers, so a trace of millions of rows costs the
    garbage collector nothing to traverse (a list of strings would be rescanned on every full
    collection of a long run).
    """

    __slots__ = ("append", "cats", "data", "floated", "kind")

    def __init__(self, kind: str, n_missing: int = 0, streamed: int = 0) -> None:
        """``n_missing`` rows held here without a value; ``streamed`` earlier rows already
        handed to the table's sink (also without a value, and they count for the type)."""
        self.kind = kind
        # an int column turned float here (its ints became floats, whatever it became later):
        # the text of ints already written must change as the whole column's would
        self.floated = False
        self.cats: dict[Any, int] = {}
        if kind == "f":
            self.data: Any = array("d", [math.nan]) * n_missing
        elif kind == "i" and not (n_missing or streamed):
            self.data = array("q")
        elif kind == "i":  # an int column with earlier missing rows starts as float (NaN)
            self.kind = "f"
            self.data = array("d", [math.nan]) * n_missing
        elif kind == "c":
            self.data = array("i", [self._code(None)]) * n_missing
        else:
            self.kind = "o"
            self.data = [None] * n_missing
        self.append = self._append_cat if self.kind == "c" else self.data.append

    def _code(self, v: Any) -> int:
        c = self.cats.get(v)
        if c is None:
            if not (v is None or isinstance(v, str)):
                raise TypeError("categorical columns hold strings")
            c = self.cats[v] = len(self.cats)
        return c

    def _append_cat(self, v: Any) -> None:
        self.data.append(self._code(v))

    def values(self) -> list[Any]:
        if self.kind == "c":
            inv = list(self.cats)
            return [inv[c] for c in self.data]
        return list(self.data)

    def _to_kind(self, kind: str) -> None:
        old = self.values()
        self.floated = self.floated or (self.kind == "i" and kind == "f")
        self.kind = kind
        self.cats = {}
        if kind == "f":
            self.data = array("d", [math.nan if v is None else float(v) for v in old])
        else:
            self.data = old
        self.append = self.data.append

    def push(self, v: Any) -> None:
        """Append one value, widening the column type if it does not fit."""
        try:
            self.append(v)
            return
        except (TypeError, OverflowError):
            pass
        if self.kind == "i" and (v is None or isinstance(v, (float, np.floating))):
            self._to_kind("f")
            self.append(math.nan if v is None else v)
        else:
            self._to_kind("o")
            self.append(v)

    def push_many(self, values: tuple[Any, ...]) -> None:
        """Append a batch of values (C-level extend when they all fit)."""
        data = self.data
        if isinstance(data, list):
            data.extend(values)
            return
        try:
            if self.kind == "c":
                cats = self.cats
                try:  # every value a known category: one C-level map
                    codes = list(map(cats.__getitem__, values))
                except KeyError:  # new categories (a chunk's columns start without any)
                    for v in dict.fromkeys(values):  # in order of first appearance
                        if v not in cats:
                            self._code(v)
                    codes = list(map(cats.__getitem__, values))
                data.extend(array("i", codes))
            else:
                # array(typecode, tuple) takes a fast path that array.extend(tuple) does not,
                # and it fails as a whole (no partial append) when a value does not fit
                data.extend(array(data.typecode, values))
        except (TypeError, OverflowError):
            for v in values:
                self.push(v)

    def fill_missing(self, count: int = 1) -> None:
        if self.kind == "f":
            self.data.extend([math.nan] * count)
        elif self.kind == "i":
            self._to_kind("f")
            self.data.extend([math.nan] * count)
        elif self.kind == "c":
            self.data.extend(array("i", [self._code(None)]) * count)
        else:
            self.data.extend([None] * count)

    def extend(self, values: np.ndarray) -> None:
        if self.kind == "f":
            self.data.frombytes(np.ascontiguousarray(values, dtype=np.float64).tobytes())
        elif self.kind == "i" and values.dtype.kind in "iub":
            self.data.frombytes(np.ascontiguousarray(values, dtype=np.int64).tobytes())
        else:
            self.push_many(tuple(values.tolist()))

    def array(self) -> Any:
        """The values as an array without a copy: float64 ("f"), int64 ("i"), int32 codes into
        :attr:`cats` ("c"); the list itself ("o"). A view: valid until the column grows."""
        if self.kind == "o":
            return self.data
        dtype = np.float64 if self.kind == "f" else np.int64 if self.kind == "i" else np.int32
        return np.frombuffer(self.data, dtype=dtype) if len(self.data) else np.zeros(0, dtype)


def _series(name: str, kind: str, values: Any, cats: list[Any], index: pd.Index | None) -> pd.Series:
    """A column as a Series (``kind``, ``values`` and ``cats`` as :meth:`_Column.array` gives
    them; float64 / int64 values are used, not copied): "c" and "o" as object columns."""
    if kind in "fi":
        return pd.Series(values, name=name, index=index)
    if kind == "c":
        inv = np.empty(len(cats), dtype=object)
        inv[:] = cats
        values = inv[values] if len(inv) else np.empty(0, dtype=object)
    return pd.Series(values, name=name, dtype=object, index=index)


def _kind_of(v: Any) -> str:
    if isinstance(v, (bool, np.bool_)):
        return "o"
    if isinstance(v, (int, np.integer)):
        return "i"
    if isinstance(v, (float, np.floating)):
        return "f"
    if isinstance(v, str):
        return "c"
    return "o"


class _Chunk:
    """Rows a streamed table hands to its sink, as arrays in the table's column order: the CSV
    sink formats them as they are (no DataFrame round trip), :meth:`frame` gives the DataFrame
    :meth:`Table.frame` would (the parquet sink, pandas' CSV path).

    ``columns``: name -> (kind, values, categories), as :meth:`_Column.array` gives them
    (float64 / int64 arrays, int32 codes into the categories, a list of objects), each owned."""

    __slots__ = ("columns", "n")

    def __init__(self, columns: dict[str, tuple[str, Any, list[Any]]], n: int) -> None:
        self.columns = columns
        self.n = n

    @classmethod
    def take(cls, columns: Mapping[str, _Column], n: int, rows: np.ndarray | None = None) -> _Chunk:
        """Copies of the ``n`` rows held in ``columns``, or of the rows ``rows`` (indices, in
        that order)."""
        out: dict[str, tuple[str, Any, list[Any]]] = {}
        for key, col in columns.items():
            a = col.array()
            if col.kind == "o":
                a = list(a) if rows is None else [a[i] for i in rows.tolist()]
            else:
                a = a.copy() if rows is None else a[rows]
            out[key] = (col.kind, a, list(col.cats))
        return cls(out, n if rows is None else len(rows))

    def frame(self) -> pd.DataFrame:
        # one index object shared by every column: pandas then skips aligning them (half the cost)
        index = pd.RangeIndex(self.n) if self.columns else None  # (no columns: no rows)
        return pd.DataFrame(
            {k: _series(k, kind, a, cats, index) for k, (kind, a, cats) in self.columns.items()}, index=index
        )


class Table:
    """A column store for one event table.

    The kernel's hot path (:meth:`append_fast`) buffers row tuples and moves them into the
    columns in batches (one C-level ``extend`` per column), so a row costs one list append.

    Streaming (:meth:`stream_to`): once ``chunk_rows`` rows are held, they are handed to a sink
    (a file written as the run goes, or nothing for a table nobody reads) and the columns start
    empty again, keeping their types, so memory does not grow with the run's length. A table
    whose rows arrive out of time order (``packets``) hands over only the rows no later row
    can precede (:meth:`order_by_time`), so the file is sorted as :meth:`frame` sorts.
    """

    # rows buffered before they move into the columns: 512 row tuples (about 150 kB with their
    # numbers) are still in the core's cache when the columns take them and free them; 4096
    # were not in a large network (docs/performance.md, ninth pass)
    _BATCH = 512

    def __init__(self, name: str, schema: Iterable[tuple[str, str]] = ()) -> None:
        self.name = name
        self._n = 0
        self.columns: dict[str, _Column] = {c: _Column(k) for c, k in schema}
        self._schema = tuple(self.columns)
        # the columns of the row tuples in _buf, in order: the schema, a prefix of self.columns
        # (append_fast, row_buffer); a table without one: every column, as its last complete
        # row named them (append)
        self._buf_keys = self._schema
        self._buf: list[tuple[Any, ...]] = []
        self._batch = self._BATCH  # rows buffered before they move into the columns
        self._sink: _Sink | None = None
        self._chunk_rows = self._next_spill = 0
        self._streamed = 0  # rows handed to the sink
        self._watermark: Callable[[], float] | None = None
        self._floor = -math.inf  # every row not yet handed over has time >= this
        # columns -> how many rows handed to the sink had each combination of their values
        # (None: not countable, see tally)
        self._tallies: dict[tuple[str, ...], dict[tuple[Any, ...], int] | None] = {}
        # column -> the parts of it handed to the sink, chunk by chunk (see keep); None: not kept
        self._kept: dict[str, list[tuple[str, Any, list[Any]]]] | None = None

    @property
    def n(self) -> int:
        """Number of rows (including those already streamed out)."""
        return self._streamed + self._n + len(self._buf)

    def order_by_time(self, watermark: Callable[[], float]) -> None:
        """Rows arrive out of time order, but every row appended from now on has ``time >=
        watermark()`` (s): when streaming, only rows earlier than that are handed over, in
        stable time order (the order :meth:`frame` gives). A row that breaks the promise is an
        error (the file could not be sorted), never a silently misordered file."""
        self._watermark = watermark

    def tally(self, columns: tuple[str, ...]) -> None:
        """Count, as rows are handed to the sink, the rows of each combination of the values
        of ``columns`` (categorical ones): a statistic of the streamed file (the packet counts)
        without reading it back. Given up (:attr:`tallies` None) if rows were handed over
        before this call, or a chunk lacks a column or holds one that is not categorical."""
        self._tallies[tuple(columns)] = {} if not self._streamed else None

    @property
    def tallies(self) -> dict[tuple[str, ...], dict[tuple[Any, ...], int] | None]:
        """columns -> {values: rows} of every :meth:`tally` (None where it was given up)."""
        return self._tallies

    def keep(self, columns: tuple[str, ...]) -> None:
        """Keep a copy of ``columns`` as rows are handed to a CSV sink, for a reader that needs
        them whole (a protocol's metrics): :meth:`kept` then gives what reading them back from
        the file gives, without parsing it. Given up (None) if rows were handed over before
        this call, or a chunk lacks one of them, changes its type or holds a value whose text
        might not read back as it was (objects; a category that is not a plain word). Only the
        table's schema columns are kept: the read-back types those by the schema ("007" stays a
        string), while a column outside it is typed by what its text looks like."""
        ok = not self._streamed and all(c in self._schema for c in columns)
        self._kept = {c: [] for c in columns} if ok else None

    def _keep(self, chunk: _Chunk) -> None:
        """Add a chunk's kept columns (its own arrays: the chunk is not changed after this)."""
        assert self._kept is not None
        for c, parts in self._kept.items():
            part = chunk.columns.get(c)
            if (
                part is None
                or part[0] == "o"
                or (parts and parts[0][0] != part[0])
                or (part[0] == "c" and not all(v is None or _PLAIN.fullmatch(v) for v in part[2]))
            ):
                self._kept = None
                return
            parts.append(part)

    def kept(self) -> pd.DataFrame | None:
        """The kept columns (:meth:`keep`) in the table's column order, as reading them back
        from the CSV file gives them (``read_table``'s dtypes and values); None if given up or
        no row was handed over. Once: each column's chunks are let go as it is joined, so the
        memory held is about the frame's (a column read back would hold as much)."""
        kept, self._kept = self._kept, None
        if not kept or not all(kept.values()):
            return None
        out = {}
        for c in [c for c in self.columns if c in kept]:
            parts = kept.pop(c)
            if parts[0][0] == "c":
                values = [_series(c, "c", codes, cats, None).to_numpy() for _, codes, cats in parts]
            else:
                values = [a for _, a, _ in parts]
            del parts
            out[c] = pd.Series(np.concatenate(values), name=c, dtype=values[0].dtype)
            del values
        return pd.DataFrame(out, copy=False)

    def _count(self, chunk: _Chunk) -> None:
        """Add a chunk's rows to the tallies."""
        for cols, counts in self._tallies.items():
            if counts is None:
                continue
            found = [chunk.columns.get(c) for c in cols]
            parts = [p for p in found if p is not None and p[0] == "c"]
            if len(parts) != len(cols):
                self._tallies[cols] = None
                continue
            # one code per combination (mixed radix over the categories), counted in C
            code = np.zeros(chunk.n, dtype=np.int64)
            for _, codes, cats in parts:
                code = code * len(cats) + codes
            n = np.bincount(code)
            for k in np.flatnonzero(n).tolist():
                key, rest = [], k
                for _, _, cats in reversed(parts):
                    rest, i = divmod(rest, len(cats))
                    key.append(cats[i])
                values = tuple(reversed(key))
                counts[values] = counts.get(values, 0) + int(n[k])

    def stream_to(self, sink: _Sink, chunk_rows: int) -> None:
        """Hand rows to ``sink`` in chunks of about ``chunk_rows`` (rows held so far included)."""
        self._sink = sink
        self._chunk_rows = self._next_spill = max(1, int(chunk_rows))
        self._maybe_spill()

    def _flush(self) -> None:
        if not self._buf:
            return
        buf = self._buf[:]
        self._buf.clear()  # the same list object: hot-path writers may hold it (see row_buffer)
        self._push_batch([self.columns[k] for k in self._buf_keys], buf)
        if len(self.columns) != len(self._buf_keys):
            for key in list(self.columns)[len(self._buf_keys) :]:
                self.columns[key].fill_missing(len(buf))
        self._n += len(buf)
        self._maybe_spill()

    @staticmethod
    def _push_batch(cols: list[_Column], buf: list[tuple[Any, ...]]) -> None:
        """Row tuples (one value per column of ``cols``) into ``cols``: ``zip(*buf)`` and
        :meth:`_Column.push_many` per column, the reference; in C (``_fastcsv.push_rows``) for
        every column whose values all fit it as they are (exact floats and ints for "f", exact
        ints for "i", strings and None for "c", anything for "o"), the reference for the others."""
        left: Iterable[int] = range(len(cols))
        if _fastcsv is not None:
            left = _fastcsv.push_rows(buf, [(c.kind, c.data, c.cats) for c in cols])
        if left:
            values = list(zip(*buf))  # (rows shorter than cols: zip's truncation, as before)
            for j in left:
                if j < len(values):
                    cols[j].push_many(values[j])

    def _maybe_spill(self) -> None:
        if self._sink is not None:
            if self._n >= self._next_spill:
                self._spill(final=False)
            # buffer no more rows than reach the next hand-over: rows go to the sink where
            # they would if appended one by one, and a small chunk stays small in memory
            self._batch = max(1, min(self._BATCH, self._next_spill - self._n))

    def _spill(self, final: bool) -> None:
        """Hand the rows held (for a time-ordered table: those before the watermark) to the sink."""
        sink = self._sink
        assert sink is not None
        if not self._n:
            return
        columns = self.columns
        rows = kept = None  # the rows handed over, in order (None: all, as held); those kept back
        if self._watermark is not None:
            col = columns["time"]
            t = col.array() if col.kind == "f" else np.asarray(col.values(), dtype=np.float64)
            if t.min() < self._floor:
                raise RuntimeError(
                    f"trace table {self.name}: a row at t={t.min()!r} s came after rows up to "
                    f"{self._floor!r} s were written (its writer broke order_by_time's promise)"
                )
            if final:
                rows = np.argsort(t, kind="stable")  # pandas' sort_values(kind="mergesort") order
            else:
                self._floor = max(self._floor, float(self._watermark()))
                early = t < self._floor
                rows = np.flatnonzero(early)
                rows = rows[np.argsort(t[rows], kind="stable")]
                kept = np.flatnonzero(~early)
        chunk = _Chunk.take(columns, self._n, rows)
        self._reset_columns()
        if kept is not None and len(kept):
            self._push_rows(columns, kept)
        # rows kept back wait for the watermark: try again only when as many have come again
        self._next_spill = self._chunk_rows + self._n
        if chunk.n:
            floated = frozenset(k for k, c in columns.items() if c.floated)
            sink.write(chunk, {k: c.kind for k, c in self.columns.items()}, floated)
            self._streamed += chunk.n
            if self._tallies:
                self._count(chunk)
            if self._kept is not None:
                self._keep(chunk)

    def _held_frame(self) -> pd.DataFrame:
        return _Chunk.take(self.columns, self._n).frame()

    def _reset_columns(self) -> None:
        """Empty every column, keeping its (possibly widened) type."""
        self.columns = {k: _Column(c.kind) for k, c in self.columns.items()}
        self._n = 0

    def _push_rows(self, columns: Mapping[str, _Column], rows: np.ndarray) -> None:
        """Put the rows ``rows`` (indices) of ``columns``, the columns before
        :meth:`_reset_columns`, back (the few a time-ordered table keeps)."""
        for key, col in self.columns.items():
            old = columns[key]
            a = old.array()
            if old.kind in "fi":  # the same kind: the bytes as they are
                col.data.frombytes(a[rows].tobytes())
            elif old.kind == "c":
                inv = list(old.cats)
                col.push_many(tuple([inv[c] for c in a[rows].tolist()]))
            else:
                col.push_many(tuple([a[i] for i in rows.tolist()]))
        self._n = len(rows)

    def close(self) -> Path | None:
        """Hand every remaining row to the sink and close it; returns the file written (None
        without a sink, or for a table whose rows were dropped)."""
        if self._sink is None:
            return None
        self._flush()
        self._spill(final=True)
        self._sink.close(self._held_frame())
        return self._sink.path

    def append(self, **row: Any) -> None:
        """Append one row; unknown columns are created (earlier rows get missing values).

        A row of every column in the buffer's order (a protocol logging the same columns each
        time) is buffered as :meth:`append_fast` buffers: ``push_many`` widens a column's type
        exactly as ``push`` would, row by row."""
        self.append_row(tuple(row), tuple(row.values()))

    def append_row(self, keys: tuple[str, ...], values: tuple[Any, ...]) -> None:
        """:meth:`append` of the row whose columns ``keys`` (distinct) hold ``values``: a
        writer that has them as tuples (a node's ``log``) need not build the dict."""
        if keys == self._buf_keys and len(keys) == len(self.columns):
            buf = self._buf
            buf.append(values)
            if len(buf) >= self._batch:
                self._flush()
            return
        row = dict(zip(keys, values))
        if self._buf:
            self._flush()
        cols = self.columns
        for key, v in row.items():
            col = cols.get(key)
            if col is None:
                col = cols[key] = _Column(_kind_of(v), self._n, self._streamed)
            col.push(v)
        if len(row) != len(cols):
            for key, col in cols.items():
                if key not in row:
                    col.fill_missing()
        self._n += 1
        if not self._schema and len(row) == len(cols):  # later rows like this one are buffered
            self._buf_keys = keys
        self._maybe_spill()

    def row_buffer(self) -> list[tuple[Any, ...]]:
        """The list that :meth:`append_fast` appends to, for writers that append row tuples
        (schema order) themselves; they should call :meth:`flush_if_large` now and then."""
        return self._buf

    def flush_if_large(self) -> None:
        if len(self._buf) >= self._batch:
            self._flush()

    def append_fast(self, values: tuple[Any, ...]) -> None:
        """Append a row given in schema order (the kernel's hot path: no checks, no new columns)."""
        buf = self._buf
        buf.append(values)
        if len(buf) >= self._batch:
            self._flush()

    def extend(self, **cols: np.ndarray) -> None:
        """Append many rows at once from equal-length 1-D arrays (e.g. sampled positions)."""
        self._flush()
        lengths = {len(v) for v in cols.values()}
        if len(lengths) != 1:
            raise ValueError(f"table {self.name}: columns of unequal length {sorted(lengths)}")
        (m,) = lengths
        for key, v in cols.items():
            col = self.columns.get(key)
            arr = np.asarray(v)
            if col is None:
                kind = "f" if arr.dtype.kind == "f" else "i" if arr.dtype.kind in "iu" else "o"
                col = self.columns[key] = _Column(kind, self._n, self._streamed)
            col.extend(arr)
        for key, col in self.columns.items():
            if key not in cols:
                col.fill_missing(m)
        self._n += m
        self._maybe_spill()

    def frame(self) -> pd.DataFrame:
        """The rows held in memory as a DataFrame (all of them unless streaming)."""
        self._flush()
        if not self.columns:
            return pd.DataFrame()
        df = self._held_frame()
        key = _SORT_BY.get(self.name)
        if key is not None and len(df):
            df = df.sort_values(key, kind="mergesort", ignore_index=True)
        return df


#: category values a table keeps (Table.keep) as they are: their CSV text reads back unchanged
#: (no quotes, spaces or empty strings, which read back as missing)
_PLAIN = re.compile(r"[A-Za-z0-9_.:+-]+")

#: rows a streamed table holds before handing them to its file (~0.5 MB of columns for
#: ``packets``; formatting a chunk as CSV briefly takes several times that, and the heap keeps
#: that high-water mark: 16384 rows cost STVF's Table-1 run, at 100 s, 17 MiB more peak
#: memory for no measurable CPU, docs/performance.md)
CHUNK_ROWS = 4096


class Trace:
    """All event tables of a run. ``append(table, **row)`` from anywhere in the kernel.

    By default every table is kept in memory (:meth:`frames`). After :meth:`stream` each table
    goes where ``route(name)`` says, as the run goes: a file (written in chunks) or nowhere;
    :meth:`close` then finishes the files.
    """

    def __init__(self, config: TraceConfig | None = None) -> None:
        self.config = config or TraceConfig()
        self.tables: dict[str, Table] = {name: Table(name, schema) for name, schema in SCHEMAS.items()}
        self._route: Callable[[str], Path | None] | None = None
        self._fmt = "csv"
        self._chunk_rows = CHUNK_ROWS

    def table(self, name: str) -> Table:
        t = self.tables.get(name)
        if t is None:
            check_table_name(name)
            t = self.tables[name] = Table(name, SCHEMAS.get(name, ()))
            if self._route is not None:
                self._attach(t)
        return t

    def append(self, table: str, **row: Any) -> None:
        self.table(table).append(**row)

    def stream(self, route: Callable[[str], Path | None], fmt: str = "csv", chunk_rows: int | None = None) -> None:
        """Stream every table (those that exist and those made later): ``route(name)`` is the
        file to write it to (``.csv`` or ``.parquet`` as ``fmt``), or None to keep none of
        its rows. Rows go out in chunks of ``chunk_rows``; the files are byte for byte what
        :meth:`write` gives for the same rows."""
        if fmt not in ("csv", "parquet"):
            raise ValueError(f"unknown trace format {fmt!r} (use 'csv' or 'parquet')")
        self._route, self._fmt = route, fmt
        self._chunk_rows = CHUNK_ROWS if chunk_rows is None else chunk_rows
        for t in self.tables.values():
            self._attach(t)

    def _attach(self, t: Table) -> None:
        assert self._route is not None
        path = self._route(t.name)
        sink: _Sink
        if path is None:
            sink = _Discard()
        elif self._fmt == "csv":
            sink = _CsvSink(path)
        else:
            sink = _ParquetSink(path, t.name)
        t.stream_to(sink, self._chunk_rows)

    def close(self) -> dict[str, tuple[Path | None, int]]:
        """Finish streaming: table name -> (its file or None, its number of rows)."""
        return {name: (t.close(), t.n) for name, t in self.tables.items()}

    def frames(self) -> dict[str, pd.DataFrame]:
        """Every table as a DataFrame (DESIGN.md columns first, extra columns after)."""
        if self._route is not None:
            raise RuntimeError("frames(): the tables are streamed to files; read those (trace.load)")
        return {name: t.frame() for name, t in self.tables.items()}

    def write(self, directory: str | os.PathLike[str], fmt: str = "csv") -> list[Path]:
        """Write one file per table into ``directory`` (created); returns the paths."""
        return write_frames(self.frames(), directory, fmt)


#: what a table name may be: it becomes a file name inside the output directory
TABLE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")


def check_table_name(name: object) -> None:
    """Raise ValueError unless ``name`` is a valid trace table name (:data:`TABLE_NAME`: letters,
    digits, ``_``, ``.``, ``-``, not starting with ``.`` or ``-``), so that no table can be
    written outside the output directory or as a hidden file."""
    if not isinstance(name, str) or not TABLE_NAME.fullmatch(name):
        raise ValueError(
            f"invalid trace table name {name!r}: use letters, digits, '_', '.' and '-' (not first), no path separators"
        )


def write_frames(frames: Mapping[str, pd.DataFrame], directory: str | os.PathLike[str], fmt: str = "csv") -> list[Path]:
    """Write DataFrames as ``<name>.csv`` (or ``.parquet``, which needs pyarrow); every name
    is checked (:func:`check_table_name`) before anything is written."""
    for name in frames:
        check_table_name(name)
    out = Path(directory)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, df in frames.items():
        if fmt == "csv":
            p = out / f"{name}.csv"
            # lineterminator fixed so Windows and POSIX produce the same bytes
            df.to_csv(p, index=False, lineterminator="\n")
        elif fmt == "parquet":
            try:
                import pyarrow  # noqa: F401
            except ImportError as e:  # pragma: no cover - depends on the environment
                raise RuntimeError("fmt='parquet' needs pyarrow (pip install 'aquasim-py[parquet]')") from e
            p = out / f"{name}.parquet"
            df.to_parquet(p, index=False)
        else:
            raise ValueError(f"unknown trace format {fmt!r} (use 'csv' or 'parquet')")
        paths.append(p)
    return paths


# --------------------------------------------------------------------------- streaming sinks
class _Sink(Protocol):
    """Where a streamed table's chunks go (:meth:`Trace.stream`)."""

    @property
    def path(self) -> Path | None:
        """The file written (None: nothing is)."""
        ...

    def write(self, chunk: _Chunk, kinds: Mapping[str, str], floated: frozenset[str] = frozenset()) -> None:
        """Append the rows of ``chunk``; ``kinds``: every column's type so far (as :class:`_Column`);
        ``floated``: the columns that went from int to float in this chunk (even if they are
        objects now)."""
        ...

    def close(self, empty: pd.DataFrame) -> None:
        """Finish the file; ``empty``: the table's columns without rows (for a table never written)."""
        ...


class _Discard:
    """A table nobody reads (not written, not used by a metric): its rows are dropped."""

    path: Path | None = None

    def write(self, chunk: _Chunk, kinds: Mapping[str, str], floated: frozenset[str] = frozenset()) -> None:
        pass

    def close(self, empty: pd.DataFrame) -> None:
        pass


def _widened(old: Mapping[str, str], new: Mapping[str, str], floated: frozenset[str], k: str) -> bool:
    """Whether the ints written so far in column ``k`` are floats in the whole table: it was
    an int column and turned float since, even if it holds objects now (int -> float ->
    object converts the ints on the way; int -> object keeps them)."""
    return old[k] == "i" and (new[k] == "f" or k in floated)


def _reformats(old: Mapping[str, str], new: Mapping[str, str], floated: frozenset[str] = frozenset()) -> bool:
    """Whether text already written must change: a column added (a new header field and an
    empty field on every earlier row) or an int column turned float ("3" becomes "3.0",
    :func:`_widened`). Any other change (to "o", any object) keeps each value's text: pandas
    writes a float, an int or a string in an object column as in a typed one."""
    return any(k not in old for k in new) or any(_widened(old, new, floated, k) for k in old)


#: strings whose CSV field text a sink remembers (category values: a handful per column)
_QUOTED_MAX = 65_536


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


def _csv_lines(
    labels: list[str], columns: list[tuple[str, Any, list[Any]]], n: int, header: bool, quoted: dict[Any, str]
) -> str | None:
    """The CSV text of ``n`` rows given as columns (kind, values, categories) as in
    :class:`_Chunk`, byte for byte what ``DataFrame.to_csv`` writes for them, formatted a
    column at a time instead of through pandas' per-field path (about 5 us per ``packets``
    row there, 1-2 us here; docs/performance.md, "End to end"). ``quoted`` caches string
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


def _csv_bytes(
    labels: list[str], columns: list[tuple[str, Any, list[Any]]], n: int, header: bool, quoted: dict[Any, str]
) -> bytes | None:
    """:func:`_csv_lines`' text as UTF-8 bytes (None where it declines), the rows formatted in
    C when the module is built (``_fastcsv.csv_rows``: each distinct float's ``repr`` once,
    ints, fields of strings prepared here as :func:`_object_fields` makes them, one buffer).
    tests/test_trace_csv.py holds both paths equal to ``DataFrame.to_csv``."""
    if _fastcsv is None or n == 0 or len(labels) < 2:
        text = _csv_lines(labels, columns, n, header, quoted)
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
    rows = _fastcsv.csv_rows(cols, n)
    return _header_line(labels, quoted).encode("utf-8") + rows if header else rows


class _CsvSink:
    """A table appended to ``path`` chunk by chunk, byte for byte what :func:`write_frames`
    writes for the whole table.

    pandas formats each field from its value and its column's dtype alone, so chunks written
    one after another give the whole table's bytes as long as each chunk has the column types
    the table ends with. When a later chunk changes them in a way that changes earlier text
    (:func:`_reformats`), the file written so far is rewritten once, chunk by chunk."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._kinds: dict[str, str] | None = None
        self._quoted: dict[Any, str] = {}  # a string (None, bool) -> its CSV field (_object_fields), kept across chunks

    def write(self, chunk: _Chunk, kinds: Mapping[str, str], floated: frozenset[str] = frozenset()) -> None:
        if self._kinds is not None and _reformats(self._kinds, kinds, floated):
            self._rewrite(kinds, floated)
        first = self._kinds is None
        data = _csv_bytes(list(chunk.columns), list(chunk.columns.values()), chunk.n, first, self._quoted)
        if data is None:  # a column the bulk formatter does not take: pandas writes the chunk
            with open(self.path, "w" if first else "a", encoding="utf-8", newline="") as f:
                chunk.frame().to_csv(f, index=False, header=first, lineterminator="\n")
        else:
            with open(self.path, "wb" if first else "ab") as f:
                f.write(data)
        self._kinds = dict(kinds)
        if len(self._quoted) > _QUOTED_MAX:  # a column of ever new strings: do not keep them all
            self._quoted.clear()

    def _rewrite(self, kinds: Mapping[str, str], floated: frozenset[str]) -> None:
        assert self._kinds is not None
        widened = [k for k in self._kinds if _widened(self._kinds, kinds, floated, k)]
        added = [k for k in kinds if k not in self._kinds]
        tmp = self.path.with_name(self.path.name + ".rewrite")
        with open(tmp, "w", encoding="utf-8", newline="") as f:
            pd.DataFrame(columns=list(kinds)).to_csv(f, index=False, lineterminator="\n")
            # every field read back as its exact text ("" = missing) and written again as is,
            # except the widened ints, which become floats as an in-memory column does
            chunks = pd.read_csv(self.path, dtype=str, keep_default_na=False, na_filter=False, chunksize=CHUNK_ROWS)
            for chunk in chunks:
                for k in widened:
                    chunk[k] = pd.to_numeric(chunk[k].mask(chunk[k] == "")).astype(np.float64)
                for k in added:
                    chunk[k] = ""
                chunk[list(kinds)].to_csv(f, index=False, header=False, lineterminator="\n")
        os.replace(tmp, self.path)

    def close(self, empty: pd.DataFrame) -> None:
        if self._kinds is None:  # no rows at all: the header alone, as write_frames gives
            empty.to_csv(self.path, index=False, lineterminator="\n")


class _ParquetSink:
    """A table written to ``path`` as one Parquet row group per chunk (pyarrow). Column types
    are inferred as ``DataFrame.to_parquet`` infers them for the whole table; a chunk that
    widens them (int to float, a new column, a type for a column all missing so far) rewrites
    the row groups written so far once, row group by row group."""

    def __init__(self, path: Path, name: str) -> None:
        self.path = path
        self.name = name
        self._file = path  # the file being written (another name while rewriting)
        self._writer: Any = None
        self._schema: Any = None

    @staticmethod
    def _arrow(df: pd.DataFrame) -> Any:
        import pyarrow as pa

        return pa.Table.from_pandas(df, preserve_index=False).replace_schema_metadata(None)

    def write(self, chunk: _Chunk, kinds: Mapping[str, str], floated: frozenset[str] = frozenset()) -> None:
        import pyarrow as pa
        import pyarrow.parquet as pq

        t = self._arrow(chunk.frame())
        if self._writer is None:
            self._schema = t.schema
            self._writer = pq.ParquetWriter(self._file, t.schema)
        elif not t.schema.equals(self._schema):
            try:
                schema = pa.unify_schemas([self._schema, t.schema], promote_options="permissive")
            except (pa.ArrowInvalid, pa.ArrowTypeError) as e:
                raise RuntimeError(f"trace table {self.name}: a column changed type mid-run ({e})") from None
            if not schema.equals(self._schema):
                self._rewrite(schema)
            t = _conform(t, self._schema)
        self._writer.write_table(t)

    def _rewrite(self, schema: Any) -> None:
        import pyarrow.parquet as pq

        self._writer.close()
        old = self._file
        self._file = self.path.with_name(self.path.name + ".rewrite") if old == self.path else self.path
        self._writer = pq.ParquetWriter(self._file, schema)
        src = pq.ParquetFile(old)
        for i in range(src.num_row_groups):
            self._writer.write_table(_conform(src.read_row_group(i), schema))
        src.close()
        old.unlink()
        self._schema = schema

    def close(self, empty: pd.DataFrame) -> None:
        import pyarrow.parquet as pq

        if self._writer is None:  # no rows at all
            pq.write_table(self._arrow(empty), self.path)
            return
        self._writer.close()
        if self._file != self.path:
            os.replace(self._file, self.path)


def _conform(t: Any, schema: Any) -> Any:
    """Arrow table ``t`` with ``schema``'s columns (missing ones null) and types."""
    import pyarrow as pa

    cols = [t.column(f.name).cast(f.type) if f.name in t.column_names else pa.nulls(len(t), f.type) for f in schema]
    return pa.Table.from_arrays(cols, schema=schema)


def _pandas_version() -> tuple[int, int]:
    major, minor = pd.__version__.split(".")[:2]
    return int(major), int("".join(ch for ch in minor if ch.isdigit()) or 0)


# pandas' default C float parser is not correctly rounded through 3.0.x (measured: 3.0.6 reads
# 6.40422650443282e-273 one ulp off, ~30% of random doubles); "round_trip" hands every field to
# Python's correctly rounded parser. 3.1 made that the default and deprecates the option.
_READ_CSV_KW: dict[str, Any] = {"float_precision": "round_trip"} if _pandas_version() < (3, 1) else {}


def _csv_header(path: Path) -> pd.Index | None:
    try:
        return pd.read_csv(path, nrows=0).columns
    except pd.errors.EmptyDataError:
        return None


def _read_csv(path: Path, name: str, columns: Sequence[str] | None = None) -> pd.DataFrame:
    """One CSV table with exact floats and its schema's dtypes (``columns``: only those, each
    parsed and typed as in the whole table: pandas infers a column's dtype from it alone).

    Only an empty field is missing (the writer's ``na_rep``): pandas' default NA strings would
    turn a category such as "NA" or "null" into NaN. Schema columns get their dtypes back even
    where the text cannot show them (an empty table, a category that looks like a number, a
    category column that is all missing): "c" object strings with None for missing, as
    :meth:`Table.frame` makes; "f" float64 and "i" int64 in an empty table (with rows they read
    as written: an int column with missing values was written as floats)."""
    kinds = dict(SCHEMAS.get(name, ()))
    header = _csv_header(path)
    if header is None:  # a table without columns is written as an empty line
        return pd.DataFrame()
    kw: dict[str, Any] = dict(_READ_CSV_KW)
    if columns is not None:
        header = [c for c in header if c in columns]
    if len(set(header)) == len(header):
        # the columns named even when all are read: the parse then peaks about 25 MiB lower
        # on STVF's 500-s estimates (14.5 MB; docs/performance.md, "End to end")
        kw["usecols"] = list(header)
    # categories as text: "007" or "1.50" must not become numbers
    dtype = {c: str for c in header if kinds.get(c) == "c"}
    df = pd.read_csv(path, keep_default_na=False, na_values=[""], dtype=dtype, **kw)
    for c in header:
        kind = kinds.get(c)
        if kind in ("f", "i") and len(df) == 0:  # no rows: the header alone reads as object
            df[c] = df[c].astype(np.float64 if kind == "f" else np.int64)
        elif kind == "c":
            col = df[c]
            df[c] = pd.Series(
                np.where(col.isna(), None, col.to_numpy(dtype=object)), index=df.index, dtype=object, name=c
            )
    return df


def table_columns(tables: Mapping[str, pd.DataFrame], name: str, columns: Sequence[str]) -> pd.DataFrame | None:
    """``tables[name]``'s ``columns`` (those it has, in its order); None when ``tables`` has no
    such table. From a streamed run's files (:meth:`TraceFiles.columns`, or a view of them with
    a ``columns`` method) only those columns are parsed. A table the run did not keep raises
    :class:`TableNotKept`, as ``tables[name]`` does."""
    read = getattr(tables, "columns", None)
    try:
        if read is not None:
            return read(name, columns)
        df = tables[name]
    except KeyError:
        return None
    return df[[c for c in df.columns if c in columns]]


def read_table(path: str | os.PathLike[str], name: str | None = None) -> pd.DataFrame:
    """One table file (``.csv`` or ``.parquet``) as :func:`load` reads it; ``name``: its table
    name (default the file's stem), which gives the schema's dtypes."""
    p = Path(path)
    if p.suffix == ".parquet":
        return pd.read_parquet(p)
    return _read_csv(p, p.stem if name is None else name)


def load(directory: str | os.PathLike[str]) -> dict[str, pd.DataFrame]:
    """Read every ``*.csv`` / ``*.parquet`` table of a trace directory (``summary.json`` as a dict
    under the key ``"summary"`` is left to the caller: only tables are returned).

    CSV floats are read back bit for bit, and writing the loaded frames again gives the same
    bytes (pandas 2.1 to 3.x)."""
    d = Path(directory)
    if not d.is_dir():
        raise FileNotFoundError(f"trace directory {d} does not exist")
    return {p.stem: read_table(p) for p in sorted(d.iterdir()) if p.suffix in (".csv", ".parquet")}


class TableNotKept(LookupError):
    """A table the run did not keep: not written and read by no metric (``Node.trace_tables``)."""


class TraceFiles(Mapping[str, pd.DataFrame]):
    """The tables of a streamed run (:meth:`Trace.stream`), each read from its file the first
    time it is asked for and then kept (:meth:`clear` lets go).

    ``files``: table name -> file, in the run's table order; ``rows``: their row counts;
    ``dropped``: the tables whose rows were not kept (asking for one raises
    :class:`TableNotKept`, not a silent ``None``); ``scratch``: a directory of files nobody
    asked to keep, removed with this object (or at exit); ``kept``: table name -> (columns
    kept as its file was written, :meth:`Table.kept`; every column of the table), which
    :meth:`columns` gives instead of parsing the file.
    """

    def __init__(
        self,
        files: Mapping[str, Path],
        rows: Mapping[str, int] | None = None,
        dropped: Iterable[str] = (),
        scratch: Path | None = None,
        tallies: Mapping[str, Mapping[tuple[str, ...], dict[tuple[Any, ...], int] | None]] | None = None,
        kept: Mapping[str, tuple[pd.DataFrame, Sequence[str]]] | None = None,
    ) -> None:
        self._files = dict(files)
        self._rows = dict(rows or {})
        self._dropped = set(dropped) - set(self._files)
        self._tallies = {(name, cols): t for name, ts in (tallies or {}).items() for cols, t in ts.items()}
        self._kept = dict(kept or {})
        self._cache: dict[str, pd.DataFrame] = {}
        self._column_cache: dict[tuple[str, tuple[str, ...]], pd.DataFrame] = {}
        self._memo: dict[Any, Any] = {}
        if scratch is not None:
            weakref.finalize(self, shutil.rmtree, scratch, True)

    def __getitem__(self, name: str) -> pd.DataFrame:
        df = self._cache.get(name)
        if df is None:
            path = self._files.get(name)
            if path is None:
                if name in self._dropped:
                    raise TableNotKept(
                        f"trace table {name!r} was not kept: add it to [trace] tables, or to the "
                        "trace_tables of the protocol whose metrics read it"
                    )
                raise KeyError(name)
            df = self._cache[name] = read_table(path, name)
        return df

    def __contains__(self, name: object) -> bool:
        return name in self._files

    def __iter__(self) -> Iterator[str]:
        return iter(self._files)

    def __len__(self) -> int:
        return len(self._files)

    def path(self, name: str) -> Path:
        """The file table ``name`` was written to."""
        return self._files[name]

    def columns(self, name: str, columns: Sequence[str]) -> pd.DataFrame:
        """Table ``name``'s ``columns`` (those it has, in its order), as ``self[name]`` has them,
        parsing only those from the file (a metric that needs 4 of ``packets``' 13 columns
        reads about a quarter); kept until :meth:`clear`. Missing table: as ``self[name]``."""
        if name in self._cache or name not in self._files:
            df = self[name]
            return df[[c for c in df.columns if c in columns]]
        key = (name, tuple(columns))
        df = self._column_cache.get(key)
        kept, header = self._kept.get(name, (None, ()))
        if df is None and kept is not None:
            want = [c for c in header if c in columns]
            if all(c in kept.columns for c in want):
                df = self._column_cache[key] = kept[want]
        if df is None:
            path = self._files[name]
            if path.suffix == ".parquet":
                import pyarrow.parquet as pq

                names = pq.read_schema(path).names
                df = pd.read_parquet(path, columns=[c for c in names if c in columns])
            else:
                df = _read_csv(path, name, columns)
            self._column_cache[key] = df
        return df

    def rows(self, name: str) -> int:
        """Number of rows of table ``name`` (without reading it)."""
        return self._rows[name] if name in self._rows else len(self[name])

    def chunks(self, name: str, columns: Sequence[str], chunk_rows: int = CHUNK_ROWS) -> Iterator[pd.DataFrame]:
        """Table ``name``'s ``columns`` (those it has), ``chunk_rows`` rows at a time: for a
        statistic over a table too long to hold (the packet counts)."""
        if name in self._cache:
            df = self._cache[name]
            yield df[[c for c in columns if c in df.columns]]
            return
        path = self.path(name)
        if path.suffix == ".parquet":
            import pyarrow.parquet as pq

            f = pq.ParquetFile(path)
            have = [c for c in columns if c in f.schema_arrow.names]
            for batch in f.iter_batches(batch_size=chunk_rows, columns=have):
                yield batch.to_pandas()
            return
        header = _csv_header(path)
        have = [c for c in columns if header is not None and c in header]
        if not have:
            return
        # every field as its text, "" missing: counts and comparisons need nothing more
        yield from pd.read_csv(
            path, usecols=have, dtype=str, keep_default_na=False, na_values=[""], chunksize=chunk_rows
        )

    def tally(self, name: str, columns: tuple[str, ...]) -> dict[tuple[Any, ...], int] | None:
        """Rows of table ``name`` per combination of the values of ``columns``, counted as the
        file was written (:meth:`Table.tally`); None when nobody counted them."""
        if name not in self._files:
            return None
        return self._tallies.get((name, tuple(columns)))

    def memo(self, key: Any, compute: Callable[[], Any]) -> Any:
        """``compute()``, computed once per ``key`` and kept until :meth:`clear`: what two
        readers of these tables derive alike (a protocol's metrics and its derived tables)."""
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def relocate(self, old: Path, new: Path) -> None:
        """The files under ``old`` now live under ``new`` (a staged output moved into place)."""
        for name, p in self._files.items():
            if p.is_relative_to(old):
                self._files[name] = new / p.relative_to(old)

    def clear(self) -> None:
        """Forget the tables read so far (they are read again when asked for)."""
        self._cache.clear()
        self._column_cache.clear()
        self._memo.clear()
        self._kept.clear()


def read_summary(directory: str | os.PathLike[str]) -> dict[str, Any]:
    """The ``summary.json`` of a trace directory."""
    return json.loads((Path(directory) / "summary.json").read_text())
