"""Reading trace files back: one table, a run's directory, a streamed run's files on demand."""

from __future__ import annotations

import json
import os
import shutil
import weakref
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .schema import CHUNK_ROWS, SCHEMAS

__all__ = ["TableNotKept", "TraceFiles", "load", "read_summary", "read_table", "table_columns"]


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
        # on STVF's 500-s estimates (14.5 MB)
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

    def chunks(
        self, name: str, columns: Sequence[str], chunk_rows: int = CHUNK_ROWS, *, typed: bool = False
    ) -> Iterator[pd.DataFrame]:
        """Table ``name``'s ``columns`` (those it has), ``chunk_rows`` rows at a time: for a
        statistic over a table too long to hold (the packet counts). From a CSV file every
        field comes as its text ("" missing), or with ``typed`` as :meth:`columns` parses it
        (exact floats; a column's dtype inferred per chunk, so give only columns that are
        never missing)."""
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
        if typed:
            kinds = dict(SCHEMAS.get(name, ()))
            text = {c: str for c in have if kinds.get(c) == "c"}
            yield from pd.read_csv(
                path,
                usecols=have,
                dtype=text,
                keep_default_na=False,
                na_values=[""],
                chunksize=chunk_rows,
                **_READ_CSV_KW,
            )
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
