"""One trace table: rows appended during a run, streamed to its file in chunks, read as a
DataFrame after."""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from . import csvfmt
from .columns import Chunk, Column, kind_of, series
from .schema import SORT_BY

if TYPE_CHECKING:  # pragma: no cover
    from .sinks import Sink

__all__ = ["Table"]

#: category values a table keeps (Table.keep) as they are: their CSV text reads back unchanged
#: (no quotes, spaces or empty strings, which read back as missing)
_PLAIN = re.compile(r"[A-Za-z0-9_.:+-]+")


class Table:
    """A column store for one event table.

    :meth:`append` buffers row tuples and moves them into the columns in batches (one C-level
    ``extend`` per column), so a row of the usual columns costs one list append;
    :meth:`extend` appends many rows given as columns (arrays).

    Streaming (:meth:`stream_to`): once ``chunk_rows`` rows are held, they are handed to a sink
    (a file written as the run goes, or nothing for a table nobody reads) and the columns start
    empty again, keeping their types, so memory does not grow with the run's length. A table
    whose rows arrive out of time order (``packets``) hands over only the rows no later row
    can precede (:meth:`order_by_time`), so the file is sorted as :meth:`frame` sorts.
    """

    # rows buffered before they move into the columns: 512 row tuples (about 150 kB with their
    # numbers) are still in the core's cache when the columns take them and free them; 4096
    # were not in a large network (200 nodes, bench_kernel.py)
    _BATCH = 512

    def __init__(self, name: str, schema: Iterable[tuple[str, str]] = ()) -> None:
        self.name = name
        self._n = 0
        self.columns: dict[str, Column] = {c: Column(k) for c, k in schema}
        self._schema = tuple(self.columns)
        # the columns of the row tuples in _buf, in order: the schema, a prefix of self.columns,
        # or every column as the last complete row named them (append; of a schema table, the
        # schema's first)
        self._buf_keys = self._schema
        self._buf: list[tuple[Any, ...]] = []
        # _buf_keys while they name every column (a row of them can be buffered), else None
        self._fast_keys: tuple[str, ...] | None = self._schema
        self._batch = self._BATCH  # rows buffered before they move into the columns
        self._sink: Sink | None = None
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

    def _keep(self, chunk: Chunk) -> None:
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
                values = [series(c, "c", codes, cats, None).to_numpy() for _, codes, cats in parts]
            else:
                values = [a for _, a, _ in parts]
            del parts
            out[c] = pd.Series(np.concatenate(values), name=c, dtype=values[0].dtype)
            del values
        return pd.DataFrame(out, copy=False)

    def _count(self, chunk: Chunk) -> None:
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

    def stream_to(self, sink: Sink, chunk_rows: int) -> None:
        """Hand rows to ``sink`` in chunks of about ``chunk_rows`` (rows held so far included)."""
        self._sink = sink
        self._chunk_rows = self._next_spill = max(1, int(chunk_rows))
        self._maybe_spill()

    def _flush(self) -> None:
        if not self._buf:
            return
        buf = self._buf
        self._buf = []
        self._push_batch([self.columns[k] for k in self._buf_keys], buf)
        if len(self.columns) != len(self._buf_keys):
            for key in list(self.columns)[len(self._buf_keys) :]:
                self.columns[key].fill_missing(len(buf))
        self._n += len(buf)
        self._maybe_spill()

    @staticmethod
    def _push_batch(cols: list[Column], buf: list[tuple[Any, ...]]) -> None:
        """Row tuples (one value per column of ``cols``) into ``cols``: ``zip(*buf)`` and
        :meth:`Column.push_many` per column, the reference; in C (``csvfmt.fastcsv.push_rows``) for
        every column whose values all fit it as they are (exact floats and ints for "f", exact
        ints for "i", strings and None for "c", anything for "o"), the reference for the others."""
        left: Iterable[int] = range(len(cols))
        fast = csvfmt.fastcsv
        if fast is not None:
            left = fast.push_rows(buf, [(c.kind, c.data, c.cats) for c in cols])
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
        chunk = Chunk.take(columns, self._n, rows)
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
        return Chunk.take(self.columns, self._n).frame()

    def _reset_columns(self) -> None:
        """Empty every column, keeping its (possibly widened) type."""
        self.columns = {k: Column(c.kind) for k, c in self.columns.items()}
        self._n = 0

    def _push_rows(self, columns: Mapping[str, Column], rows: np.ndarray) -> None:
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

    def append(self, values: tuple[Any, ...], columns: tuple[str, ...] | None = None) -> None:
        """Append one row: ``values`` of ``columns`` (distinct names; None: the table's schema,
        in order). Columns the table does not have yet are created (earlier rows get missing
        values); columns the row does not name get a missing value.

        A row of every column in the order of the rows before it (the packets table; a protocol
        logging the same columns each time) costs one list append: such rows are buffered and
        moved into the columns in batches (``push_many`` widens a column's type exactly as
        one value at a time would)."""
        keys = self._schema if columns is None else columns
        if keys == self._fast_keys:
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
                col = cols[key] = Column(kind_of(v), self._n, self._streamed)
            col.push(v)
        if len(row) != len(cols):
            for key, col in cols.items():
                if key not in row:
                    col.fill_missing()
        self._n += 1
        # later rows like this one are buffered: a row of every column (of a schema table: the
        # schema's first, in order, then extra ones, e.g. a range-dependent channel's)
        if len(row) == len(cols) and (not self._schema or tuple(keys[: len(self._schema)]) == self._schema):
            self._buf_keys = tuple(keys)
        self._fast_keys = self._buf_keys if len(self._buf_keys) == len(cols) else None
        self._maybe_spill()

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
                col = self.columns[key] = Column(kind, self._n, self._streamed)
            col.extend(arr)
        for key, col in self.columns.items():
            if key not in cols:
                col.fill_missing(m)
        self._n += m
        self._fast_keys = self._buf_keys if len(self._buf_keys) == len(self.columns) else None
        self._maybe_spill()

    def frame(self) -> pd.DataFrame:
        """The rows held in memory as a DataFrame (all of them unless streaming)."""
        self._flush()
        if not self.columns:
            return pd.DataFrame()
        df = self._held_frame()
        key = SORT_BY.get(self.name)
        if key is not None and len(df):
            df = df.sort_values(key, kind="mergesort", ignore_index=True)
        return df
